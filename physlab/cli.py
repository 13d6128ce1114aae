"""The ``physlab`` command.

    physlab reproduce [--out reports] [--lessons 01 03]   execute lessons headless, save figures
    physlab execute lessons/01_*.ipynb                    execute notebooks in place (maintainers)
    physlab lessons                                        list the lessons
    physlab animate --drawing tree --out tree.gif          a drawing blown by a wind stroke

``python -m physlab.cli ...`` works the same without the console script.
"""
from __future__ import annotations

import argparse
import base64
import sys
import time
from pathlib import Path

from physlab._io import atomic_write

LESSONS_DIR = Path(__file__).resolve().parent.parent / "lessons"


def lesson_paths(selection=None, lessons_dir=LESSONS_DIR):
    """Lesson notebooks in order; ``selection``: list of number prefixes like ``["01", "3"]``."""
    paths = sorted(Path(lessons_dir).glob("[0-9][0-9]_*.ipynb"))
    if not paths:
        raise FileNotFoundError(f"no lessons found in {lessons_dir}")
    if selection:
        wanted = {s.zfill(2) for s in selection}
        paths = [p for p in paths if p.name[:2] in wanted]
        if not paths:
            raise ValueError(f"no lesson matches {selection}; available: "
                             + ", ".join(p.name[:2] for p in sorted(Path(lessons_dir).glob('*.ipynb'))))
    return paths


def execute_notebook(path, timeout=600, cwd=None):
    """Execute a notebook with nbclient (a fresh python3 kernel) and return it."""
    import nbformat
    from nbclient import NotebookClient

    nb = nbformat.read(path, as_version=4)
    NotebookClient(nb, timeout=timeout, kernel_name="python3",
                   resources={"metadata": {"path": str(cwd or Path(path).parent)}}).execute()
    return nb


def save_figures(nb, out_dir):
    """Write every PNG output of an executed notebook to ``out_dir/cellNN_k.png``."""
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    written = []
    for ci, cell in enumerate(nb.cells):
        for k, out in enumerate(cell.get("outputs", [])):
            png = out.get("data", {}).get("image/png")
            if png:
                p = out_dir / f"cell{ci:02d}_{k}.png"
                atomic_write(p, lambda tmp, png=png: Path(tmp).write_bytes(base64.b64decode(png)))
                written.append(p)
    return written


def reproduce(out="reports", lessons=None, progress=True):
    """Execute the lessons headless (not in place) and save their figures under ``out/``.

    Returns ``{lesson name: [png paths]}``."""
    from tqdm.auto import tqdm

    results = {}
    paths = lesson_paths(lessons)
    for path in tqdm(paths, desc="lessons", disable=not progress):
        t0 = time.perf_counter()
        nb = execute_notebook(path)
        results[path.stem] = save_figures(nb, Path(out) / path.stem)
        if progress:
            tqdm.write(f"{path.name}: {len(results[path.stem])} figures, {time.perf_counter() - t0:.1f} s")
    return results


EXAMPLES = """examples:
  physlab lessons
  physlab animate --drawing tree --duration 2 --out tree.gif
  physlab reproduce --lessons 01 04 --out reports
"""


def _parser():
    from physlab._cli import Parser

    parser = Parser(prog="physlab", description=__doc__.split("\n\n")[0], epilog=EXAMPLES)
    sub = parser.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("reproduce", help="execute lessons headless and save their figures",
                       epilog="example:\n  physlab reproduce --lessons 01 03 --out reports")
    r.add_argument("--out", default="reports")
    r.add_argument("--lessons", nargs="*", help="number prefixes, e.g. 01 03 (default: all)")
    e = sub.add_parser("execute", help="execute notebooks in place (stores outputs)",
                       epilog="example:\n  physlab execute lessons/02_second_order_and_implicit.ipynb")
    e.add_argument("paths", nargs="+")
    e.add_argument("--timeout", type=int, default=600)
    sub.add_parser("lessons", help="list the lessons", epilog="example:\n  physlab lessons")
    a = sub.add_parser("animate", help="PhysAnimator pipeline: drawing -> simulation -> GIF/MP4",
                       epilog="examples:\n  physlab animate --drawing tree --out tree.gif\n"
                              "  physlab animate --drawing my_drawing.png --duration 3 --out a.mp4")
    a.add_argument("--drawing", default="tree", help="ball, tree, flag, jelly or an image path")
    a.add_argument("--duration", type=float, default=2.0, help="seconds (0 < duration <= 60)")
    a.add_argument("--fps", type=int, default=24, help="frames per second (1..120)")
    a.add_argument("--E", type=float, default=1.5e5, help="Young's modulus (per px²)")
    a.add_argument("--nu", type=float, default=0.3)
    a.add_argument("--strength", type=float, default=4e4, help="wind particle strength s")
    a.add_argument("--direction-deg", type=float, default=0.0)
    a.add_argument("--out", default="animation.gif", help=".gif or .mp4")
    a.add_argument("--control-out", default=None, help="also write the control images here")
    return parser


#: Video files ``physlab animate`` writes, by extension.
VIDEO_SUFFIXES = (".gif", ".mp4")


def _check_animate(args):
    for flag, value in (("--out", args.out), ("--control-out", args.control_out)):
        if value is not None and Path(value).suffix.lower() not in VIDEO_SUFFIXES:
            kind = Path(value).suffix or "a file without extension"
            raise ValueError(f"{flag} {value}: cannot write {kind}; use one of "
                             f"{', '.join(VIDEO_SUFFIXES)}")
    if not (0 < args.duration <= 60):
        raise ValueError(f"--duration must be in (0, 60] seconds, got {args.duration}")
    if not (1 <= args.fps <= 120):
        raise ValueError(f"--fps must be in 1..120, got {args.fps}")


def main(argv=None):
    """Entry point of the ``physlab`` command; returns the exit status."""
    from physlab._cli import run

    args = _parser().parse_args(argv)
    return run("physlab", lambda: _dispatch(args), debug=args.debug)


def _dispatch(args):
    if args.cmd == "reproduce":
        res = reproduce(args.out, args.lessons)
        print(f"wrote {sum(len(v) for v in res.values())} figures to {args.out}/")
    elif args.cmd == "execute":
        import nbformat

        for p in args.paths:
            if not Path(p).is_file():
                raise FileNotFoundError(f"no notebook at {p}")
            t0 = time.perf_counter()
            nb = execute_notebook(p, timeout=args.timeout)
            # atomic: a failed run never leaves a half-written lesson
            atomic_write(p, lambda tmp, nb=nb: nbformat.write(nb, tmp), ".ipynb")
            print(f"{p}: executed in {time.perf_counter() - t0:.1f} s")
    elif args.cmd == "animate":
        from physlab.demos.physanimator import animate_drawing

        _check_animate(args)
        r = animate_drawing(drawing=args.drawing, duration=args.duration, fps=args.fps, E=args.E,
                            nu=args.nu, strength=args.strength, direction_deg=args.direction_deg,
                            out=args.out, control_out=args.control_out)
        print(f"wrote {len(r.frames)} frames to {args.out} ({r.animation.stats['triangles']} "
              f"triangles, simulated in {r.animation.stats['seconds']:.1f} s)")
    else:
        for p in lesson_paths():
            print(p.name)


if __name__ == "__main__":
    sys.exit(main())
