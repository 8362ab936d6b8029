"""``WrenchSample.with_wrench`` (the compensation's hot path) is ``dataclasses.replace``."""

from __future__ import annotations

import dataclasses

import numpy as np

from forcelearn.devices import WrenchSample


def test_with_wrench_keeps_every_other_field_as_replace_does() -> None:
    """Every field but the wrench kept, for defaults and set values; a new field fails here."""
    names = [f.name for f in dataclasses.fields(WrenchSample)]
    assert names == ["wrench", "timestamp_s", "counter", "saturated", "sensor_dt_s"]
    wrench = np.arange(6.0)
    for sample in (WrenchSample(np.zeros(6), 1.5, 7),
                   WrenchSample(np.ones(6), 2.5, 65535, (True,) + (False,) * 5, 0.001)):
        fast, slow = sample.with_wrench(wrench), dataclasses.replace(sample, wrench=wrench)
        for f in dataclasses.fields(WrenchSample):
            assert getattr(fast, f.name) is getattr(slow, f.name), f.name
        assert fast.wrench is wrench


def test_of_is_the_constructor() -> None:
    """``WrenchSample.of`` (the driver's hot path) builds the object ``__init__`` builds."""
    wrench = np.arange(6.0)
    for args in ((wrench, 1.5, 7, (False,) * 6, None),
                 (wrench, 2.5, 65535, (True,) + (False,) * 5, 0.001)):
        fast, slow = WrenchSample.of(*args), WrenchSample(*args)
        assert type(fast) is WrenchSample and vars(fast).keys() == vars(slow).keys()
        for f in dataclasses.fields(WrenchSample):
            assert getattr(fast, f.name) is getattr(slow, f.name), f.name
        assert repr(fast) == repr(slow)
        with np.testing.assert_raises(dataclasses.FrozenInstanceError):
            fast.counter = 3  # type: ignore[misc]  # frozen as the constructor's
