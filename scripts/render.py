#!/usr/bin/env python3
"""Render a frame of an output .xdmf off-screen, as ParaView shows it after Warp By Vector: the body
deformed by `displacement` (times --scale), coloured by a field.

    .venv/bin/python scripts/render.py output/bracket.xdmf -o output/bracket.png --field von_mises
"""
import argparse
import sys


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("xdmf")
    ap.add_argument("-o", "--output", required=True, help="PNG file")
    ap.add_argument("--frame", type=int, default=-1, help="frame index (default: the last)")
    ap.add_argument("--field", default="displacement", help="point or cell field to colour by")
    ap.add_argument("--scale", type=float, default=1.0, help="displacement magnification")
    a = ap.parse_args(argv)
    import pyvista as pv
    pv.OFF_SCREEN = True
    r = pv.get_reader(a.xdmf)
    n = r.number_time_points
    if not -n <= a.frame < n:
        print(f"render: error: {a.xdmf} has no frame {a.frame} (it has {n})", file=sys.stderr)
        return 2
    r.set_active_time_point(a.frame % n)
    mesh = r.read()
    if a.field not in mesh.array_names:
        print(f"render: error: no field '{a.field}' (fields: {', '.join(mesh.array_names)})", file=sys.stderr)
        return 2
    mesh = mesh.warp_by_vector("displacement", factor=a.scale)
    p = pv.Plotter(off_screen=True, window_size=(1000, 700))
    p.add_mesh(mesh, scalars=a.field, cmap="viridis", show_edges=False)
    p.add_text(f"t = {r.time_values[a.frame % n]:.4g}", font_size=10)
    p.view_isometric()
    p.screenshot(a.output)
    print(a.output)
    return 0


if __name__ == "__main__":
    sys.exit(main())
