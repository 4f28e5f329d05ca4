"""The output's cost per frame against the number of frames before it (issue 36: the XDMF was rewritten whole
at every frame, so a run's output time grew with the square of its frames).

    python scripts/bench_output.py OUT [--frames 10,1000,10000] [--level 1]

Each run: the drop scene on the bar at -level L, -dt 1e-3, one frame per step (-frames_per_second 1000), to
-final_time frames/1000, one rank, -log_view; printed: the wall time, the seconds of the Output stage, its
seconds per frame, and the sizes of the .h5 and the .xdmf. Flat seconds per frame = a frame costs the same
however many came before it.
"""
import argparse
import os
import re
import sys

sys.path.insert(0, os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

from hyperelastic.studies.experiments.runner import last_line, run_hyperelastic  # noqa: E402


def stages(log):
    """{stage name: seconds} from -log_view's "Summary of Stages" table."""
    out, on = {}, False
    with open(log) as fh:
        for line in fh:
            if line.startswith("Summary of Stages"):
                on = True
            elif on and re.match(r"\s*\d+:\s+\S", line):
                m = re.match(r"\s*\d+:\s+(.+?):\s+([0-9.eE+-]+)", line)
                out[m.group(1).strip()] = float(m.group(2))
            elif on and out and not line.strip():
                break
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("out")
    ap.add_argument("--frames", default="10,1000,10000")
    ap.add_argument("--level", type=int, default=1)
    a = ap.parse_args()
    os.makedirs(a.out, exist_ok=True)
    print(f"{'frames':>7} {'wall s':>8} {'Output s':>9} {'ms/frame':>9} {'Step s':>8} {'h5 MB':>7} {'xdmf MB':>8}")
    for n in map(int, a.frames.split(",")):
        path, log = os.path.join(a.out, f"drop_{n}.h5"), os.path.join(a.out, f"drop_{n}.log")
        rc, err, wall = run_hyperelastic(["run", "drop", "-level", a.level, "-dt", "1e-3", "-frames_per_second", 1000,
                                       "-final_time", n / 1000, "-output", path, "-quiet", "-log_view", f":{log}"],
                                      path, timeout=36000)
        if rc != 0:
            sys.exit(f"run with {n} frames failed: {last_line(err, rc)}")
        st = stages(log)
        out = st.get("Output", float("nan"))
        xdmf = os.path.splitext(path)[0] + ".xdmf"
        print(f"{n:>7} {wall:>8.2f} {out:>9.3f} {1e3 * out / n:>9.3f} {st.get('Step', float('nan')):>8.2f} "
              f"{os.path.getsize(path) / 1e6:>7.1f} {os.path.getsize(xdmf) / 1e6:>8.2f}", flush=True)


if __name__ == "__main__":
    main()
