"""Every script of this folder by name: `python scripts` lists them (each one's first line), `python scripts NAME
[ARGS]` runs scripts/NAME.py (or NAME.sh with bash) with ARGS, as `python scripts/NAME.py ARGS` would."""
import os
import runpy
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
SKIP = ("__main__.py", "launch.py")


def scripts():
    """{name: (path, its first line)} of the folder's scripts."""
    out = {}
    for f in sorted(os.listdir(HERE)):
        path = os.path.join(HERE, f)
        if f in SKIP or not f.endswith((".py", ".sh")):
            continue
        with open(path, encoding="utf-8") as fh:
            text = fh.read()
        if f.endswith(".py"):
            first = text.split('"""', 2)[1].strip().splitlines()[0] if text.lstrip().startswith(('"""', "#!")) and \
                '"""' in text else ""
        else:
            first = next((ln.lstrip("# ").strip() for ln in text.splitlines()[1:] if ln.startswith("#")), "")
        out[os.path.splitext(f)[0]] = (path, first)
    return out


def main(argv):
    found = scripts()
    if not argv or argv[0] in ("-h", "--help", "list"):
        width = max(map(len, found))
        print("python scripts NAME [ARGS]:\n" + "\n".join(f"  {n:<{width}}  {line}" for n, (_, line) in found.items()))
        return 0
    name = argv[0][:-3] if argv[0].endswith((".py", ".sh")) else argv[0]
    if name not in found:
        print(f"scripts: no script '{name}' (python scripts lists them)", file=sys.stderr)
        return 2
    path = found[name][0]
    if path.endswith(".sh"):
        return subprocess.call(["bash", path, *argv[1:]])
    sys.argv = [path, *argv[1:]]
    sys.path.insert(0, os.path.dirname(HERE))
    runpy.run_path(path, run_name="__main__")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
