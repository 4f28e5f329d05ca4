"""Rank 0's metadata per frame of the per-rank output against the rank count (issue 74 item 5), without the ranks:
the virtual datasets FILE.h5 gets for a frame, made as the writer makes them, for P = 16 ... 1,000 rank files.

    python scripts/bench_output_meta.py OUT [--ranks 16,128,1000] [--fields 8] [--frames 50]

`per rank` is what a frame cost before the series (output/ranks.py): each field's frames/<i>/<field> a virtual
dataset with one mapping per rank file (output.ranks.virtual). `series` is today's: each field's series/<field> made
once per part with one mapping per rank file (virtual_series), then per frame frames/<i>/<field> with one mapping to
row i of it (frame_view). The rank files need not exist to make the mappings (HDF5 opens them when read), so this
times rank 0's own HDF5 work at rank counts this machine cannot run. Printed: ms per frame (the series' one-off
set-up apart), the file's bytes per frame."""
import argparse
import os
import sys
import time

import h5py
import numpy as np

sys.path.append(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))     # (after an installed hyperelastic)

from hyperelastic.output.ranks import frame_view, virtual, virtual_series  # noqa: E402
from hyperelastic.output.writer import FIELD_LINKS, FRAME_LINKS, _compact_group  # noqa: E402


def one(path, P, fields, frames, series):
    """(seconds of the series' set-up, seconds per frame, bytes per frame) of `frames` frames of `fields` cell fields
    over P rank files of 1,000 cells each."""
    rows = 1000
    part = {"files": [f"x.h5.d/r{r:05d}.h5" for r in range(P)], "nodes": [rows] * P, "cells": [rows] * P,
            "first": 0, "series": True}
    n = rows * P
    with h5py.File(path, "w") as f:
        _compact_group(f, "frames", FRAME_LINKS)
        t0 = time.perf_counter()
        if series:
            for k in range(fields):
                virtual_series(f, [part], f"f{k}", n, (), np.float64, "cell")
        f.flush()
        t1 = time.perf_counter()
        size0 = os.path.getsize(path)
        for i in range(frames):
            g = _compact_group(f["frames"], str(i), FIELD_LINKS)
            for k in range(fields):
                if series:
                    frame_view(g, f"f{k}", n, (), i)
                else:
                    virtual(g, f"f{k}", [(p, f"frames/{i}/f{k}", rows) for p in part["files"]], ())
            f.flush()
        t2 = time.perf_counter()
    return t1 - t0, (t2 - t1) / frames, (os.path.getsize(path) - size0) / frames


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--ranks", default="16,128,1000")
    ap.add_argument("--fields", type=int, default=8)
    ap.add_argument("--frames", type=int, default=50)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    print(f"{'ranks':>6} {'per rank ms/frame':>17} {'KB/frame':>8} {'series ms/frame':>15} {'KB/frame':>8} "
          f"{'series set-up ms':>16}", flush=True)
    for P in map(int, a.ranks.split(",")):
        _, old, old_b = one(os.path.join(a.out, "old.h5"), P, a.fields, a.frames, False)
        setup, new, new_b = one(os.path.join(a.out, "new.h5"), P, a.fields, a.frames, True)
        print(f"{P:>6} {1e3 * old:>17.2f} {old_b / 1e3:>8.1f} {1e3 * new:>15.2f} {new_b / 1e3:>8.1f} "
              f"{1e3 * setup:>16.1f}", flush=True)


if __name__ == "__main__":
    main()
