"""scripts/diagnose_measured.py's all-loops table: re-running some units keeps the others'
rows (the trails themselves run by the script; here its table from rows of the shape it writes)."""

import argparse
import importlib.util
import json
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "scripts"))
_spec = importlib.util.spec_from_file_location("_diagnose_measured", ROOT / "scripts" / "diagnose_measured.py")
dm = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(dm)


def _args(output: Path) -> argparse.Namespace:
    return argparse.Namespace(output=output, decimate=16, seed=0, ar1="off", student_t=None,
                              least_squares_signatures=False, no_backward=True, no_swap=False, relays_from_smooth_gap=False)


def _rows(unit: str, rmse: int) -> list[str]:
    return [f"| {unit} | base model | | {rmse} | 4000 | | 40 |",
            f"| | + asymmetry | -12.0 | {rmse} → {rmse - 100} | 4000 → 3900 | 50 ± 10 | |",
            f"| | left unexplained: structure versus mesh torque | | {rmse - 100} | | | |"]


def _entry(rmse: int, with_rows: bool) -> dict:
    entry = {"added": ["asymmetry"], "rmse_base": rmse, "rmse_final": rmse - 100}
    return entry | ({"rows": _rows("x", rmse)} if with_rows else {})


def test_a_rerun_keeps_the_other_units_rows_in_name_order(tmp_path):
    entries = {"b-unit": _entry(900, False), "a-unit": _entry(800, False)}
    dm.write_table(_args(tmp_path), entries, {"a-unit": _rows("a-unit", 800), "b-unit": _rows("b-unit", 900)})
    text = (tmp_path / "measured-trail.md").read_text()
    assert text.index("| a-unit |") < text.index("| b-unit |")
    # entries written before the rows were recorded with them take theirs from the table
    kept, rows = dm.kept_units(tmp_path, ["a-unit"])
    assert set(kept) == {"b-unit"} and rows["b-unit"] == _rows("b-unit", 900)
    kept["c-unit"], rows["c-unit"] = _entry(700, True), _rows("c-unit", 700)
    dm.write_table(_args(tmp_path), kept, rows)
    again = dm.rows_by_unit((tmp_path / "measured-trail.md").read_text())
    assert list(again) == ["b-unit", "c-unit"] and again["b-unit"] == _rows("b-unit", 900)
    assert list(json.loads((tmp_path / "measured-trail.json").read_text())) == ["b-unit", "c-unit"]


def test_a_kept_unit_without_rows_anywhere_stops_with_one_line(tmp_path):
    (tmp_path / "measured-trail.json").write_text(json.dumps({"a-unit": _entry(800, False)}))
    (tmp_path / "measured-trail.md").write_text("caption\n\n| unit | step |\n| --- | --- |\n")
    with pytest.raises(SystemExit, match="unit a-unit has no trail rows"):
        dm.kept_units(tmp_path, [])


def test_no_table_yet_keeps_nothing(tmp_path):
    assert dm.kept_units(tmp_path, ["a-unit"]) == ({}, {})


def test_relays_from_the_smooth_gap_is_an_opt_in_of_the_catalog(tmp_path):
    """``--relays-from-smooth-gap`` swaps the relay gap for one tested on the smooth gap too; the
    rest of the catalog, and the default run's catalog, unchanged."""
    from torsionfit.diagnose import CATALOG, GapRelays

    assert dm.catalog(_args(tmp_path)) is CATALOG
    opted = dm.catalog(argparse.Namespace(**{**vars(_args(tmp_path)), "relays_from_smooth_gap": True}))
    assert [e.name for e in opted] == [e.name for e in CATALOG]
    relays = [e for e in opted if isinstance(e, GapRelays)]
    assert len(relays) == 1 and relays[0].from_smooth_gap
    assert not next(e for e in CATALOG if isinstance(e, GapRelays)).from_smooth_gap
