"""The ``physlab`` command: one subcommand per job, each a thin wrapper of one library function
with the same keyword names.

    physlab lessons                                        list the lessons
    physlab reproduce [--out reports] [--lessons 01 03]   execute lessons headless, save figures
                      [--timeout 600]                      (seconds per cell; execute too)
    physlab execute lessons/01_*.ipynb                    execute notebooks in place (maintainers)
    physlab animate --drawing tree --out tree.gif          a drawing blown by a wind stroke
    physlab inbetween K0.png K1.png --skeleton0 s0.json --skeleton1 s1.json --frames 11 --out DIR
    physlab generate "a person walks" --out walk.bvh       text (+ keypose / trajectories) -> motion
    physlab train motion --stage base --out base.pt        train the motion generator
    physlab evaluate inbetween|motion ...                  the evaluations of parts 3 and 4

``python -m physlab.cli ...`` works the same without the console script.
"""
from __future__ import annotations

import argparse
import base64
import subprocess
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

    from physlab._kernel import notebook_client

    nb = nbformat.read(path, as_version=4)
    # The client polls in slices (physlab._kernel): nbclient's own client sometimes slept
    # through a reply that was already there until the whole cell timeout had passed.
    # The kernel's own stdout/stderr (start-up warnings) go nowhere; cell output reaches
    # the notebook through IOPub regardless.
    notebook_client(nb, timeout=timeout, kernel_name="python3",
                    resources={"metadata": {"path": str(cwd or Path(path).parent)}}).execute(
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
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


def reproduce(out="reports", lessons=None, progress=True, timeout=600):
    """Execute the lessons headless (not in place) and save their figures under ``out/``;
    ``timeout``: seconds any one cell may run.

    Returns ``{lesson name: [png paths]}``."""
    from tqdm.auto import tqdm

    results = {}
    paths = lesson_paths(lessons)
    for path in tqdm(paths, desc="lessons", disable=not progress):
        t0 = time.perf_counter()
        nb = execute_notebook(path, timeout=timeout)
        results[path.stem] = save_figures(nb, Path(out) / path.stem)
        if progress:
            tqdm.write(f"{path.name}: {len(results[path.stem])} figures, {time.perf_counter() - t0:.1f} s")
    return results


EXAMPLES = """examples:
  physlab lessons
  physlab animate --drawing tree --duration 2 --out tree.gif
  physlab inbetween key0.png key1.png --skeleton0 k0.json --skeleton1 k1.json --frames 11 --out frames/
  physlab generate "a person walks" --trajectory pelvis=path.npy --out walk.bvh
  physlab train motion --stage base --steps 4000 --out runs/base.pt
  physlab evaluate inbetween --pairs my_pair/ --out runs/my_pair
  physlab evaluate motion --control data/motion/sketch2anim_control.pt --windows 16
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
    r.add_argument("--timeout", type=int, default=600, help="seconds any one cell may run")
    e = sub.add_parser("execute", help="execute notebooks in place (stores outputs)",
                       epilog="example:\n  physlab execute lessons/02_second_order_and_implicit.ipynb")
    e.add_argument("paths", nargs="+")
    e.add_argument("--timeout", type=int, default=600, help="seconds any one cell may run")
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
    i = sub.add_parser("inbetween", help="skeleton-driven inbetweening of two keyframes",
                       epilog="example:\n  physlab inbetween key0.png key1.png --skeleton0 k0.json "
                              "--skeleton1 k1.json --frames 11 --out frames/\n\nA skeleton file "
                              "is JSON {\"names\": [...], \"parents\": [...], \"xy\": [[x, y], ...]}"
                              " (pixels, y down; Skeleton.to_dict) or an AnimatedDrawings "
                              "char_cfg.yaml.")
    i.add_argument("key0", help="first keyframe image (PNG, RGBA or on a light background)")
    i.add_argument("key1", help="last keyframe image, same size")
    i.add_argument("--skeleton0", required=True, help="skeleton of key0 (.json or char_cfg.yaml)")
    i.add_argument("--skeleton1", required=True, help="skeleton of key1, same joints")
    i.add_argument("--frames", type=int, default=11, help="frames including both keys")
    i.add_argument("--out", required=True, help="folder for frame_000.png ... and contact.png")
    g = sub.add_parser("generate", help="Sketch2Anim motion from an action text (+ conditions)",
                       epilog="examples:\n  physlab generate \"a person walks\" --out walk.bvh\n"
                              "  physlab generate \"a person runs\" --keypose pose.npy "
                              "--trajectory pelvis=path.npy --out run.gif\n"
                              "  physlab generate \"a person walks\" --trajectory pelvis=drawn.npy "
                              "--camera 1,20,45 --out walk.bvh\n"
                              "  physlab generate \"a person walks\" --sketch sketch.json "
                              "--out walk.bvh\n\n--keypose: a .npy "
                              "(22, 3) array in metres; --trajectory JOINT=FILE: a .npy (t_r, 3) "
                              "array for pelvis, left_foot, right_foot, head, left_wrist or "
                              "right_wrist (canonical frame, see physlab.motion.sampling). "
                              "(22, 2) / (t_r, 2) arrays are a sketch in the normalised image "
                              "coordinates of --camera (physlab.motion.camera). --sketch: a "
                              "sketch saved by the lesson-10 canvas (.json: strokes, joints, "
                              "camera; its action word unless ACTION is given) or a .png of a "
                              "black stick figure with red trajectory strokes (front view "
                              "unless --camera).")
    g.add_argument("action", nargs="?", default=None,
                   help='action text, e.g. "a person walks" (optional with a .json --sketch)')
    g.add_argument("--sketch", default=None, help="a sketch .json (physlab.motion.sketch) or "
                                                  "a stick-figure .png")
    g.add_argument("--keypose", default=None, help="(22, 3) .npy keypose in metres")
    g.add_argument("--keypose-at", default="first", choices=("first", "last"))
    g.add_argument("--trajectory", action="append", default=[], metavar="JOINT=FILE",
                   help="(t_r, 3) .npy trajectory of a joint (repeatable)")
    g.add_argument("--camera", default=None, metavar="SCALE,PITCH,YAW[,ROLL]",
                   help="the view a 2D keypose / trajectory was drawn in (degrees)")
    g.add_argument("--seed", type=int, default=0)
    g.add_argument("--guidance-scale", type=float, default=None,
                   help="text CFG scale w (default 2.5, or 1 with --keypose/--trajectory)")
    g.add_argument("--steps", type=int, default=None,
                   help="DDIM steps (default: generate's, physlab.motion.sampling.DEFAULT_STEPS)")
    g.add_argument("--checkpoint", default=None, help="default: the shipped control checkpoint")
    g.add_argument("--out", required=True, help=".bvh (Blender), .gif or .npy (joints)")
    t = sub.add_parser("train", help="train a model: physlab train motion ...",
                       epilog="example:\n  physlab train motion --stage base --steps 4000 "
                              "--out runs/base.pt\n(all flags: physlab train motion --help)")
    t.add_argument("what", choices=("motion",))
    t.add_argument("args", nargs=argparse.REMAINDER,
                   help="flags of the training (all of them: physlab train motion --help)")
    e = sub.add_parser("evaluate", help="physlab evaluate inbetween|motion ...",
                       epilog="examples:\n  physlab evaluate inbetween --pairs 2 --size 256\n"
                              "  physlab evaluate inbetween --pairs my_pair/ --out runs/my_pair"
                              "   (one's own keys, skeletons, gt_<t>.png)\n"
                              "  physlab evaluate motion --control data/motion/"
                              "sketch2anim_control.pt --windows 16\n(all flags: physlab "
                              "evaluate inbetween --help, physlab evaluate motion --help)")
    e.add_argument("what", choices=("inbetween", "motion"))
    e.add_argument("args", nargs=argparse.REMAINDER,
                   help="flags of the evaluation (physlab evaluate WHAT --help)")
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
    # `physlab train motion ... --debug`: the flag is among the passed-through arguments
    debug = args.debug or "--debug" in getattr(args, "args", ())
    return run("physlab", lambda: _dispatch(args), debug=debug)


def _dispatch(args):
    if args.cmd in ("reproduce", "execute") and args.timeout <= 0:
        raise ValueError(f"--timeout must be a positive number of seconds per cell, got "
                         f"{args.timeout}")
    if args.cmd == "reproduce":
        res = reproduce(args.out, args.lessons, timeout=args.timeout)
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
        from physlab.physanimator.pipeline import animate_drawing

        _check_animate(args)
        r = animate_drawing(drawing=args.drawing, duration=args.duration, fps=args.fps, E=args.E,
                            nu=args.nu, strength=args.strength, direction_deg=args.direction_deg,
                            out=args.out, control_out=args.control_out)
        print(f"wrote {len(r.frames)} frames to {args.out} ({r.animation.stats['triangles']} "
              f"triangles, simulated in {r.animation.stats['seconds']:.1f} s)")
    elif args.cmd == "inbetween":
        _inbetween(args)
    elif args.cmd == "generate":
        _generate(args)
    elif args.cmd in ("train", "evaluate"):
        # `physlab train motion ...` is `python -m physlab.motion.train ...` under the physlab
        # name (its help, examples and errors say `physlab train motion`); likewise evaluate
        from physlab._cli import run_subcommand

        if args.cmd == "train":
            from physlab.motion.train import _parser as parser, main
        elif args.what == "motion":
            from physlab.motion.evaluate import _parser as parser, main
        else:
            from physlab.inbetween.evaluate import _parser as parser, main
        run_subcommand(f"physlab {args.cmd} {args.what}", parser(), main, args.args)
    else:
        for p in lesson_paths():
            print(p.name)


def _inbetween(args):
    import numpy as np

    from physlab.image import read_image, to_uint8
    from physlab.inbetween import inbetween
    from physlab.inbetween.pair_folder import read_skeleton
    from physlab.inbetween.plots import contact_sheet

    keys = [read_image(k, name) for k, name in ((args.key0, "key0"), (args.key1, "key1"))]
    s0, s1 = (read_skeleton(args.skeleton0, "--skeleton0"),
              read_skeleton(args.skeleton1, "--skeleton1"))
    res = inbetween(keys[0], keys[1], s0, s1, args.frames, progress=True)
    out = Path(args.out)
    for k, frame in enumerate(res.frames):
        atomic_write(out / f"frame_{k:03d}.png",
                     lambda tmp, f=frame: _write_png(tmp, to_uint8(np.asarray(f))), ".png")
    contact_sheet(res.frames, out / "contact.png")
    print(f"wrote {len(res.frames)} frames and contact.png to {out}/")


def _write_png(path, image):
    import imageio.v3 as iio

    iio.imwrite(path, image, extension=".png")


def _generate(args):
    import numpy as np

    from physlab.motion import generate, joints_to_bvh

    def load(path, what):
        if not Path(path).is_file():
            raise FileNotFoundError(f"{what} {path}: no such file")
        try:
            return np.load(path, allow_pickle=False)
        except ValueError as e:
            raise ValueError(f"{what} {path}: not a .npy array ({e})") from None

    suffix = Path(args.out).suffix.lower()
    if suffix not in (".bvh", ".gif", ".npy"):
        raise ValueError(f"--out {args.out}: cannot write {suffix or 'a file without extension'}"
                         f"; use .bvh, .gif or .npy")
    trajectories = {2: {}, 3: {}}
    for item in args.trajectory:
        joint, sep, path = item.partition("=")
        if not sep:
            raise ValueError(f"--trajectory {item!r}: expected JOINT=FILE, e.g. pelvis=path.npy")
        a = load(path, f"--trajectory {joint}")
        trajectories[2 if a.ndim == 2 and a.shape[-1] == 2 else 3][joint] = a
    keypose = {2: None, 3: None}
    if args.keypose is not None:
        a = load(args.keypose, "--keypose")
        keypose[2 if a.shape[-1:] == (2,) else 3] = a
    camera = None
    if args.camera is not None:
        from physlab.motion import Camera

        try:
            values = [float(v) for v in args.camera.split(",")]
        except ValueError:
            values = []
        if len(values) not in (3, 4):
            raise ValueError(f"--camera {args.camera!r}: expected SCALE,PITCH,YAW[,ROLL] in "
                             f"degrees, e.g. 1,20,45")
        camera = Camera(*values)
    keypose_at = args.keypose_at
    if args.sketch is not None:
        from physlab.motion.sketch import Sketch, sketch_from_png

        if keypose[2] is not None or trajectories[2]:
            raise ValueError("--sketch already holds the drawn keypose and trajectories; leave "
                             "out the (22, 2) / (t_r, 2) --keypose / --trajectory arrays")
        path = Path(args.sketch)
        if not path.is_file():
            raise FileNotFoundError(f"--sketch {path}: no such file")
        if path.suffix.lower() == ".png":
            sk = sketch_from_png(path, args.action or "a person walks", camera)
        else:
            sk = Sketch.load(path)
            if camera is not None:
                sk.camera = camera
        cond = sk.conditions()
        keypose[2], trajectories[2] = cond["keypose_2d"], cond["trajectories_2d"] or {}
        camera, keypose_at = cond["camera"], cond["keypose_at"]
        args.action = cond["action"] if args.action is None else args.action
    if args.action is None:
        raise ValueError("give the action text, e.g. physlab generate \"a person walks\" ...")
    joints = generate(args.action, keypose_3d=keypose[3], keypose_at=keypose_at,
                      trajectories_3d=trajectories[3] or None, keypose_2d=keypose[2],
                      trajectories_2d=trajectories[2] or None, camera=camera, seed=args.seed,
                      guidance_scale=args.guidance_scale, steps=args.steps,
                      checkpoint=args.checkpoint)
    if suffix == ".bvh":
        joints_to_bvh(joints, args.out)
    elif suffix == ".gif":
        from physlab.viz.view3d import motion_to_gif

        motion_to_gif(joints, args.out, backend="matplotlib")
    else:
        atomic_write(args.out, lambda tmp: np.save(tmp, joints), ".npy")
    print(f"wrote {joints.shape[0]} frames of {args.action!r} to {args.out}")


if __name__ == "__main__":
    sys.exit(main())
