"""benchmarks/tried/eval_summary.py: the endings table of hangover_check.py --by-ended is
summed per bias over the validation drive sets (apart from the simulated drives), and
the gnss false positives per kind of episode before them over the data sets."""

from __future__ import annotations

from pathlib import Path

from _script_support import load_script

es = load_script("benchmarks/tried/eval_summary.py")

_BYENDED = """simulated 1 Hz, 6 x 15 min, fault draws [0, 1, 2, 3, 4]
fixes after                 1         2
ended
jump permanent        1 of 10   1 of 10
noise permanent      19 of 19  17 of 19

driveplotr validation, positions only, native, fault draws [0, 1, 2, 3, 4]
fixes after                 1         2
ended
noise permanent        5 of 5    3 of 5

tuc validation, positions only, native, fault draws [0, 1, 2, 3, 4]
fixes after                 1         2
ended
jump permanent         0 of 10   0 of 10
noise permanent        6 of 9    0 of 9
"""

_GNSS_AFTER = """| data set | episode before | false positives | 1-5 fixes after | 6-30 | later |
|---|---|---|---|---|---|
| driveplotr | jump | 4 | 3 | 1 | 0 |
| driveplotr | noise | 14 | 13 | 1 | 0 |
| tuc | noise | 9 | 8 | 1 | 0 |
"""


def test_endings_and_gnss_false_positives_are_summed(tmp_path: Path) -> None:
    (tmp_path / "byended.txt").write_text(_BYENDED)
    (tmp_path / "gnss_after.txt").write_text(_GNSS_AFTER)
    got = es.ended_figures(tmp_path)
    assert got["first clean fix flagged after a permanent noise run, simulated 1 Hz"] == "19 of 19"
    assert got["first clean fix flagged after a permanent jump run, simulated 1 Hz"] == "1 of 10"
    assert got["first clean fix flagged after a permanent noise run, validation"] == "11 of 14"
    assert got["first clean fix flagged after a permanent jump run, validation"] == "0 of 10"
    assert got["gnss false positives after noise"] == "23"
    assert got["gnss false positives after jump"] == "4"


def test_no_files_no_figures(tmp_path: Path) -> None:
    assert es.ended_figures(tmp_path) == {}
