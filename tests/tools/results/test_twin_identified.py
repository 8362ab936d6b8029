"""The study's honesty checks: member choice against the truth, identified values, 3 sigma."""

from __future__ import annotations

from typing import Any

from forcelearn.tools.results.twin_identified import (
    identified,
    member_check,
    three_sigma_offs,
    true_member,
)

FITTED = ["linear-elastic", "linear", "nonlinear", "hysteretic"]


def _truth(**sponge: float) -> dict[str, Any]:
    base = {"relaxation_ratio": 0.3, "stiffening_exponent": 1.0, "hysteresis_loss": 0.0,
            "friction_coefficient": 0.0, "relaxation_time_s": 0.5, "stiffness_n_per_mm": 2.0}
    return {"sponge": {**base, **sponge}, "arm": {"lag_s": 0.05}, "sensor": {"noise_n": 0.2}}


def _twin(member: str, notes: list[str], rows: list[dict[str, Any]] | None = None
          ) -> dict[str, Any]:
    return {"member": member, "choice": notes, "members": [{"name": n} for n in FITTED],
            "parameters": rows or []}


def test_the_true_member_holds_every_mechanism_the_fit_considered() -> None:
    """Friction is not asked of a family without its member; hysteresis is."""
    assert true_member(_truth(), FITTED) == "linear"
    assert true_member(_truth(relaxation_ratio=0.0), FITTED) == "linear-elastic"
    assert true_member(_truth(stiffening_exponent=1.3), FITTED) == "nonlinear"
    assert true_member(_truth(hysteresis_loss=0.2, friction_coefficient=0.3),
                       FITTED) == "hysteretic"


def test_a_simpler_member_counts_only_when_the_records_could_not_tell() -> None:
    """Simpler with a 'cannot tell' note: fine; richer than the truth: wrong."""
    truth = _truth(stiffening_exponent=1.3)
    told = ["the records cannot tell linear from nonlinear (held-out ΔBIC +3.0, within 10)"]
    assert member_check("c", truth, _twin("linear", told)).verdict == "cannot tell"
    assert member_check("c", truth, _twin("linear", [])).verdict == "wrong"
    assert member_check("c", truth, _twin("nonlinear", [])).verdict == "true"
    assert member_check("c", _truth(), _twin("hysteretic", [])).verdict == "wrong"


def test_identified_values_and_three_sigma_offs() -> None:
    """Within 15 % and the parameters reported determined beyond 3 sigma of the truth."""
    rows = [{"name": "lag_s", "value": 0.06, "sigma": 0.001, "determined": True},
            {"name": "relaxation_ratio", "value": 0.31, "sigma": 0.01, "determined": True},
            {"name": "stiffness_n_per_mm", "value": 2.5, "sigma": 0.5, "determined": False}]
    twin = _twin("linear", [], rows)
    found = {i.name: i for i in identified(_truth(), twin)}
    assert not found["lag_s"].within and found["relaxation_ratio"].within
    offs = three_sigma_offs(_truth(), twin)
    assert len(offs) == 1 and offs[0].startswith("lag_s")


def test_a_cell_whose_member_lacks_relaxation_counts_as_not_identified(tmp_path: Any) -> None:
    """The relaxation's share is over every fitted cell, not only those whose member fits it."""
    import json

    from forcelearn.tools.results.twin_identified import page_lines

    (tmp_path / "cells").mkdir()
    good = [{"name": "relaxation_ratio", "value": 0.3, "sigma": 0.01, "determined": True}]
    for cell, member, rows in (("cell-01", "linear", good), ("cell-02", "linear-elastic", [])):
        (tmp_path / "cells" / f"{cell}.truth.json").write_text(json.dumps(_truth()))
        (tmp_path / cell / "twin").mkdir(parents=True)
        (tmp_path / cell / "twin" / "twin.json").write_text(json.dumps(_twin(member, [], rows)))
    lines = page_lines(tmp_path, ["cell-01", "cell-02"])
    ratio = next(line for line in lines if line.startswith("- relaxation_ratio"))
    assert "within 15% on 1/2 cells" in ratio
