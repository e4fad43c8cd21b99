"""The same drives driven elsewhere on Earth: the verdicts must not depend on where.

Each real validation drive (positions only, native rate, via ``_clean_variants.py``)
moved, track by track, to another place with its local geometry kept (east/north
metres in a tangent plane at its first fix, laid down in one at the new place):
high latitudes (Tromsø 69.6° N, Svalbard 78.2° N, where a degree of longitude is a
third and a fifth of one at the equator), the southern hemisphere (Sydney), a few
metres from the equator and the prime meridian, and at the antimeridian (Fiji,
179.999° E: a drive that heads east of its start crosses it, its longitudes wrapping
from +180 to -180). No fault is
injected: every flag is a false alarm, and every column should read as the drive as
recorded. Never the test splits. Run:

    python benchmarks/places.py [--model DIR] [--data-dir DIR]
"""

from __future__ import annotations

import pandas as pd
from _clean_variants import Rewrite, print_table

from gradgps._tracks.geo import LocalFrame


def moved_to(lat0: float, lon0: float) -> Rewrite:
    def rewrite(fixes: pd.DataFrame) -> pd.DataFrame:
        parts = []
        for _, g in fixes.groupby("track", sort=False):
            here = LocalFrame(float(g["lat"].iloc[0]), float(g["lon"].iloc[0]))
            east, north = here.to_local(g["lat"].to_numpy(), g["lon"].to_numpy())
            lat, lon = LocalFrame(lat0, lon0).to_geodetic(east, north)
            parts.append(g.assign(lat=lat, lon=(lon + 180.0) % 360.0 - 180.0))
        return pd.concat(parts).reset_index(drop=True)

    return rewrite


if __name__ == "__main__":
    print_table(
        __doc__.splitlines()[0],
        {
            "as recorded": lambda fixes: fixes,
            "Tromsø 69.6° N": moved_to(69.65, 18.96),
            "Svalbard 78.2° N": moved_to(78.22, 15.65),
            "Sydney 33.9° S": moved_to(-33.87, 151.21),
            "equator, prime meridian": moved_to(0.0005, 0.0005),
            "antimeridian (Fiji)": moved_to(-16.5, 179.999),
        },
    )
