#!/usr/bin/python3
"""Times HDF5's deflate settings on a run file's frames (the choice of runfile/run_file.cpp's kGzipLevel).

Usage: scripts/frame_compression.py RUN.h5 [--repeats 3]

Rewrites /frames/positions and /frames/velocities of RUN.h5 into a scratch file, chunked one
frame per chunk as the run file is, with each setting (no filter; gzip 1 and 4 with and without
the shuffle filter), and prints the best of the repeats' wall times and the file size. The
writer's own choice is in runfile/run_file.cpp (kGzipLevel).

The run file is read through scripts/runfile.py, like every script's; h5py is called here only
to write the scratch files, whose HDF5 filter settings are what this script measures.
"""
import argparse
import os
import tempfile
import time

import h5py

import runfile


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("run")
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    run = runfile.load(args.run, frames=True, model=False)
    if run.frames is None or run.velocities is None:
        raise SystemExit(f"{args.run}: no frames with velocities to rewrite")
    frames = [run.frames, run.velocities]
    print(f"{args.run}: {frames[0].shape[0]} frames of {frames[0].shape[1]} particles, "
          f"{2 * frames[0].nbytes / 1e6:.1f} MB of doubles")
    settings = [("none", None, None, False), ("gzip 1", "gzip", 1, False), ("gzip 1 + shuffle", "gzip", 1, True),
                ("gzip 4", "gzip", 4, False), ("gzip 4 + shuffle", "gzip", 4, True)]
    with tempfile.TemporaryDirectory() as tmp:
        path = os.path.join(tmp, "frames.h5")
        for name, comp, level, shuffle in settings:
            best = float("inf")
            for _ in range(args.repeats):
                t0 = time.perf_counter()
                with h5py.File(path, "w") as g:
                    for k, a in zip(("positions", "velocities"), frames):
                        g.create_dataset(k, data=a, chunks=(1,) + a.shape[1:], compression=comp,
                                         compression_opts=level, shuffle=shuffle)
                best = min(best, time.perf_counter() - t0)
            print(f"  {name:18s} {best:7.3f} s  {os.path.getsize(path) / 1e6:7.1f} MB")


if __name__ == "__main__":
    main()
