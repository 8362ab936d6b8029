"""One module per ``forcelearn NAME`` subcommand: ``add_arguments(parser)`` and ``run(args)``."""
