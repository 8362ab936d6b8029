"""ABB's ``egm.proto`` for RobotWare 6 and 7 and the Python modules protoc generated from them.

Both files keep ABB's field numbers and types; only the package is renamed
(``abb.egm.rw6``, ``abb.egm.rw7``) so the two can be loaded into the one default
descriptor pool. The wire format carries no package names, so the bytes are ABB's.
Regenerate with (docs/egm.md)::

    python -m grpc_tools.protoc -I. --python_out=. --pyi_out=. egm_rw6.proto egm_rw7.proto
"""
