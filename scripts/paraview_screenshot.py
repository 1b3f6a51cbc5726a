#!/usr/bin/python3
"""Renders a screenshot of a run's ParaView export (RUN.xdmf, written by `pbdbench run` or
`pbdbench export`) with ParaView, on a machine with or without a display.

    paraview_screenshot.py RUN.xdmf -o OUT.png [--field constraint_error|change|none]
                           [--frame K] [--size 1280x720]

The body is coloured by a cell field of the export (defined on every cell: runfile/xdmf.hpp),
the colliders are drawn in grey; the frame is the last one unless --frame says another (negative
counts from the end). The camera looks at the body from an oblique angle, up along gravity's
opposite (y up, unless the body lies flat in x-y).

Run with /usr/bin/python3, this script starts ParaView's pvbatch on itself; without a display
($DISPLAY unset) it runs pvbatch under xvfb-run (Debian's xvfb, installed by
scripts/install_deps.sh): Debian's ParaView is built for X and `pvpython
--force-offscreen-rendering` dies in XSync without one. The same command works on a desktop.
Exit codes: 0 written, 1 ParaView or xvfb-run missing, or the render failed, 2 bad arguments.
"""
import argparse
import os
import shutil
import subprocess
import sys

INSIDE = "PBDBENCH_PARAVIEW_SCREENSHOT"  # set when this script runs inside pvbatch


def parse(argv):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("xdmf", help="RUN.xdmf (pbdbench export)")
    ap.add_argument("-o", "--out", required=True, help="the image to write (PNG)")
    ap.add_argument("--field", default="constraint_error", choices=["constraint_error", "change", "none"])
    ap.add_argument("--frame", type=int, default=-1, help="frame index (default -1: the last)")
    ap.add_argument("--size", default="1280x720", help="image size WxH (default 1280x720)")
    args = ap.parse_args(argv)
    try:
        w, h = (int(v) for v in args.size.lower().split("x"))
        if w <= 0 or h <= 0:
            raise ValueError
    except ValueError:
        ap.error(f"--size {args.size}: expected WIDTHxHEIGHT in pixels, e.g. 1280x720")
    args.width, args.height = w, h
    if not os.path.isfile(args.xdmf):
        ap.error(f"{args.xdmf}: no such file")
    return args


def command(argv):
    """The command line that renders: pvbatch on this script, under xvfb-run without a display."""
    pvbatch = shutil.which("pvbatch")
    if pvbatch is None:
        raise SystemExit("paraview_screenshot.py: pvbatch not found: scripts/install_deps.sh installs "
                         "Debian's python3-paraview")
    cmd = [pvbatch, os.path.abspath(__file__), *argv]
    if not os.environ.get("DISPLAY"):
        xvfb = shutil.which("xvfb-run")
        if xvfb is None:
            raise SystemExit("paraview_screenshot.py: no display and no xvfb-run: scripts/install_deps.sh "
                             "installs Debian's xvfb (ParaView needs an X server to render)")
        cmd = [xvfb, "-a", *cmd]
    return cmd


def render(args):
    """Inside pvbatch: the screenshot."""
    from paraview import simple

    # An absolute name: ParaView's XDMF 3 reader resolves the data file against the XDMF's folder.
    reader = simple.XDMFReader(FileNames=[os.path.abspath(args.xdmf)])
    reader.UpdatePipelineInformation()
    times = list(reader.TimestepValues) or [0.0]
    try:
        t = times[args.frame]
    except IndexError:
        print(f"paraview_screenshot.py: --frame {args.frame}: the export has {len(times)} frames", file=sys.stderr)
        return 2
    view = simple.GetActiveViewOrCreate("RenderView")
    view.ViewSize = [args.width, args.height]
    view.ViewTime = t
    view.OrientationAxesVisibility = 0
    view.Background = [1.0, 1.0, 1.0]
    try:  # ParaView >= 5.10 keeps the background in a palette unless told otherwise
        view.UseColorPaletteForBackground = 0
    except AttributeError:
        pass
    reader.UpdatePipeline(t)
    blocks = {}
    if reader.GetDataInformation().GetDataSetTypeAsString() != "vtkMultiBlockDataSet":
        blocks["body"] = reader  # no colliders: the body alone, one data set
    else:
        for name in ("body", "colliders"):
            part = simple.ExtractBlock(Input=reader, Selectors=[f"/Root/{name}"])
            part.UpdatePipeline(t)
            if part.GetDataInformation().GetNumberOfCells() > 0:
                blocks[name] = part
    if "body" not in blocks:
        print(f"paraview_screenshot.py: {args.xdmf}: no body to draw", file=sys.stderr)
        return 1
    body = simple.Show(blocks["body"], view)
    if args.field != "none":
        simple.ColorBy(body, ("CELLS", args.field))
        body.RescaleTransferFunctionToDataRange(False, True)
        body.SetScalarBarVisibility(view, True)
        lut = simple.GetColorTransferFunction(args.field)
        bar = simple.GetScalarBar(lut, view)
        bar.Title = args.field.replace("_", " ")
        bar.ComponentTitle = ""
        bar.TitleColor = bar.LabelColor = [0.1, 0.1, 0.1]
    else:
        body.AmbientColor = body.DiffuseColor = [0.4, 0.55, 0.8]
    if "colliders" in blocks:
        col = simple.Show(blocks["colliders"], view)
        col.ColorArrayName = ["POINTS", ""]
        col.AmbientColor = col.DiffuseColor = [0.7, 0.7, 0.7]
        col.Opacity = 0.35
    # Frame the body (not the colliders' large planes), seen from the front, above and to the side.
    bounds = blocks["body"].GetDataInformation().GetBounds()
    centre = [(bounds[2 * k] + bounds[2 * k + 1]) / 2 for k in range(3)]
    size = max(bounds[2 * k + 1] - bounds[2 * k] for k in range(3)) or 1.0
    flat_in_xy = (bounds[5] - bounds[4]) < 1e-9 * size and (bounds[3] - bounds[2]) > 0
    up = [0.0, 0.0, 1.0] if flat_in_xy else [0.0, 1.0, 0.0]
    direction = [0.55, 0.35, 0.75] if not flat_in_xy else [0.55, -0.75, 0.35]
    view.CameraFocalPoint = centre
    view.CameraPosition = [c + 2.2 * size * d for c, d in zip(centre, direction)]
    view.CameraViewUp = up
    view.CameraParallelProjection = 0
    simple.Render(view)
    view.ResetCamera(bounds[0], bounds[1], bounds[2], bounds[3], bounds[4], bounds[5])
    simple.SaveScreenshot(args.out, view, ImageResolution=[args.width, args.height])
    print(f"paraview_screenshot.py: {args.out} (t = {t:.4g} s, frame {times.index(t)} of {len(times)}, "
          f"colour: {args.field})")
    return 0


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    args = parse(argv)
    if os.environ.get(INSIDE):
        return render(args)
    env = dict(os.environ, **{INSIDE: "1"})
    p = subprocess.run(command(argv), env=env)
    if p.returncode != 0 or not os.path.isfile(args.out):
        print(f"paraview_screenshot.py: ParaView failed (exit {p.returncode}); nothing written to {args.out}",
              file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    rc = main()
    if rc:  # inside pvbatch, sys.exit(0) ends in a GLXBadContext on Xvfb: leave 0 to the interpreter
        sys.exit(rc)
