"""A speed or heading column an export fills with zeros: what the detector does, what the checks say.

Exports often write a speed (and a heading) column whatever the receiver gave,
as zeros where it gave none. For every real validation drive with a reported
speed and heading (native rate), the share of clean fixes the shipped model
flags as recorded, with the speed set to 0, the heading set to 0, and both, and
the kinds of input warning (:class:`gradgps._tracks.input_checks.InputChecks`).
No fault is injected: every flag is a false alarm. Never the test splits. Run:

    python benchmarks/placeholder_speed.py [--model DIR] [--data-dir DIR]
"""

from __future__ import annotations

from _clean_variants import print_table

FILLS = {
    "as recorded": {},
    "speed 0": {"speed": 0.0},
    "heading 0": {"heading": 0.0},
    "both 0": {"speed": 0.0, "heading": 0.0},
}

if __name__ == "__main__":
    print_table(
        __doc__.splitlines()[0],
        {name: (lambda t, f=fill: t.assign(**f)) for name, fill in FILLS.items()},
        variant="+speed+heading",
    )
