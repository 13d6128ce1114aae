"""Each `physlab` subcommand runs headless on tiny input (the library does the work; these
check the wiring, the files written, the help examples and the one-line errors)."""
import contextlib
import io
import json

import numpy as np
import pytest

from physlab import cli


def _run(args, capsys):
    try:
        status = cli.main(args)
    except SystemExit as e:
        status = e.code
    out = capsys.readouterr()
    return status, out.out, out.err


def test_help_lists_every_subcommand(capsys):
    status, out, _ = _run(["--help"], capsys)
    assert status == 0
    for cmd in ("reproduce", "execute", "lessons", "animate", "inbetween", "generate", "train",
                "evaluate"):
        assert cmd in out
    assert "examples:" in out


@pytest.mark.parametrize("cmd", ["animate", "inbetween", "generate", "train", "evaluate",
                                 "reproduce", "execute", "lessons"])
def test_each_subcommand_help_shows_an_example(cmd, capsys):
    status, out, _ = _run([cmd, "--help"], capsys)
    assert status == 0 and "example" in out and f"physlab {cmd}" in out


SECOND_LEVEL = {("train", "motion"): "physlab.motion.train",
                ("evaluate", "inbetween"): "physlab.inbetween.evaluate",
                ("evaluate", "motion"): "physlab.motion.evaluate"}


@pytest.mark.parametrize("cmd", list(SECOND_LEVEL), ids=" ".join)
def test_second_level_help_names_physlab_and_shows_an_example(cmd, capsys):
    """`physlab train motion --help` is the module's help under the physlab name, examples
    included; `python -m <module> --help` keeps its own name (its parser is built afresh)."""
    import importlib

    status, out, _ = _run([*cmd, "--help"], capsys)
    prog = "physlab " + " ".join(cmd)
    assert status == 0 and out.startswith(f"usage: {prog} ")
    assert "example" in out and f"\n  {prog} --" in out, out[-600:]
    own = importlib.import_module(SECOND_LEVEL[cmd])._parser().format_help()
    assert own.startswith(f"usage: python -m {SECOND_LEVEL[cmd]} ") and prog not in own
    assert f"\n  python -m {SECOND_LEVEL[cmd]} --" in own


# ----------------------------------------------------------------- each command, headless
def test_lessons_lists_the_notebooks_in_order(capsys):
    status, out, err = _run(["lessons"], capsys)
    names = out.split()
    assert status == 0, err
    assert names[0].startswith("00_") and names == sorted(names) and len(names) >= 2
    assert all(n.endswith(".ipynb") for n in names)


def test_execute_runs_a_notebook_in_place(tmp_path, capsys):
    import nbformat

    nb = nbformat.v4.new_notebook(cells=[nbformat.v4.new_code_cell("print(6 * 7)")])
    path = tmp_path / "tiny.ipynb"
    nbformat.write(nb, path)
    status, out, err = _run(["execute", str(path), "--timeout", "60"], capsys)
    assert status == 0, err
    assert "executed in" in out and [p.name for p in tmp_path.iterdir()] == ["tiny.ipynb"]
    cell = nbformat.read(path, as_version=4).cells[0]
    assert cell.outputs[0]["text"] == "42\n"


def test_animate_writes_a_gif_with_one_frame_per_tick(tmp_path, capsys):
    import imageio.v3 as iio

    out = tmp_path / "ball.gif"
    status, text, err = _run(["animate", "--drawing", "ball", "--duration", "0.5", "--fps", "4",
                              "--out", str(out)], capsys)
    assert status == 0, err
    frames = iio.imread(out, index=None)
    assert frames.shape[0] == 3 == 0.5 * 4 + 1                       # t = 0, 0.25, 0.5 s
    assert frames.shape[1:3] == (256, 256) and "wrote 3 frames" in text
    assert frames[0].std() > 0 and not np.array_equal(frames[0], frames[-1])   # it moves


def test_evaluate_inbetween_on_one_small_pair(tmp_path, capsys):
    out = tmp_path / "eval"
    status, text, err = _run(["evaluate", "inbetween", "--pairs", "1", "--size", "64",
                              "--frames", "3", "--no-progress", "--out", str(out)], capsys)
    assert status == 0, err
    rows = json.loads((out / "rows.json").read_text())
    assert {r["method"] for r in rows} >= {"cross_dissolve", "physlab"}
    assert len({r["pair"] for r in rows}) == 1
    assert all(np.isfinite(r["psnr_mid"]) for r in rows)
    assert (out / "table.md").is_file() and "physlab" in text


#: `physlab train motion` smoke settings: a few seconds per stage on one thread.
SMOKE = ["--smoke", "--steps", "2", "--num-threads", "1", "--no-progress"]


@pytest.fixture(scope="module")
def smoke_run(real_data, tmp_path_factory):
    """`physlab train motion --smoke` of both stages: exit codes, printed text, checkpoints."""
    d = tmp_path_factory.mktemp("cli_train")
    text, status = io.StringIO(), []
    with contextlib.redirect_stdout(text):
        status.append(cli.main(["train", "motion", "--stage", "base", *SMOKE,
                                "--out", str(d / "base.pt")]))
        status.append(cli.main(["train", "motion", "--stage", "control", "--base-ckpt",
                                str(d / "base.pt"), *SMOKE, "--out", str(d / "control.pt")]))
    return {"status": status, "text": text.getvalue(), "base": d / "base.pt",
            "control": d / "control.pt"}


def test_train_motion_smoke_writes_both_stages(smoke_run):
    assert smoke_run["status"] == [0, 0]
    assert "stage base: step 2" in smoke_run["text"]
    assert "stage control: step 2" in smoke_run["text"]
    assert smoke_run["base"].is_file() and smoke_run["control"].is_file()


def test_evaluate_motion_on_a_smoke_checkpoint(smoke_run, tmp_path, capsys):
    out = tmp_path / "eval"
    status, text, err = _run(["evaluate", "motion", "--control", str(smoke_run["control"]),
                              "--windows", "1", "--steps", "1", "--no-progress",
                              "--no-body-constraints", "--out", str(out)], capsys)
    assert status == 0, err
    assert "| keypose + trajectory |" in text
    saved = json.loads((out / "rows.json").read_text())
    assert saved["config"]["windows"] == 1
    assert all(r["n_clips"] == 1 for r in saved["rows"].values())
    assert (out / "table.md").read_text().startswith("| method |")


def test_inbetween_writes_frames(tmp_path, capsys):
    import imageio.v3 as iio

    from physlab.inbetween import inbetween_benchmark

    pair = inbetween_benchmark(size=96)[0]
    key0, key1 = pair.keyframes()
    for k, (img, sk) in enumerate(((key0, pair.skeleton0), (key1, pair.skeleton1))):
        iio.imwrite(tmp_path / f"k{k}.png", img)
        (tmp_path / f"s{k}.json").write_text(json.dumps(sk.to_dict()))
    status, out, err = _run(["inbetween", str(tmp_path / "k0.png"), str(tmp_path / "k1.png"),
                             "--skeleton0", str(tmp_path / "s0.json"), "--skeleton1",
                             str(tmp_path / "s1.json"), "--frames", "3", "--out",
                             str(tmp_path / "out")], capsys)
    assert status == 0, err
    frames = sorted((tmp_path / "out").glob("frame_*.png"))
    assert len(frames) == 3 and (tmp_path / "out" / "contact.png").is_file()
    assert iio.imread(frames[1]).shape[:2] == (96, 96)


def test_inbetween_names_a_bad_skeleton_file(tmp_path, capsys):
    (tmp_path / "s.json").write_text('{"names": ["a"]}')
    (tmp_path / "k.png").write_bytes(b"")
    status, _, err = _run(["inbetween", str(tmp_path / "k.png"), str(tmp_path / "k.png"),
                           "--skeleton0", str(tmp_path / "s.json"), "--skeleton1",
                           str(tmp_path / "s.json"), "--out", str(tmp_path / "o")], capsys)
    assert status == 2 and err.count("\n") == 1 and "physlab: error:" in err


@pytest.mark.filterwarnings("ignore:the BVH reproduces the joints only")
@pytest.mark.parametrize("suffix", [".bvh", ".npy"])
def test_generate_writes_a_clip(tmp_path, suffix, capsys):
    traj = tmp_path / "pelvis.npy"
    np.save(traj, np.stack([np.zeros(10), np.full(10, 0.9), np.linspace(0, 1, 10)], 1))
    out = tmp_path / f"walk{suffix}"
    status, text, err = _run(["generate", "a person walks", "--trajectory", f"pelvis={traj}",
                              "--steps", "3", "--out", str(out)], capsys)
    assert status == 0, err
    if suffix == ".npy":
        assert np.load(out).shape == (40, 22, 3)
    else:
        from physlab.motion import read_bvh

        assert read_bvh(out).n_frames == 40


def test_generate_takes_generates_default_steps(tmp_path, capsys, monkeypatch):
    """Without --steps, `physlab generate` samples as generate() does by default."""
    import physlab.motion

    seen = {}

    def fake(action, **kw):
        seen.update(kw)
        return np.zeros((40, 22, 3))

    monkeypatch.setattr(physlab.motion, "generate", fake)
    out = tmp_path / "walk.npy"
    status, _, err = _run(["generate", "a person walks", "--out", str(out)], capsys)
    assert status == 0, err
    assert seen["steps"] is None                    # generate() then uses DEFAULT_STEPS
    _run(["generate", "a person walks", "--steps", "7", "--out", str(out)], capsys)
    assert seen["steps"] == 7


@pytest.mark.filterwarnings("ignore:the BVH reproduces the joints only")
def test_generate_from_a_2d_sketch(tmp_path, capsys):
    """A pelvis path drawn in a 3/4 view (normalised image units) and --camera: the clip's
    projection follows it (the shipped model with its default guidance)."""
    from physlab.motion import Camera

    cam = Camera(1.0, 20, 45)
    path = np.stack([np.linspace(0, 0.8, 40), np.linspace(0.8, 0.6, 40)], 1)
    np.save(tmp_path / "drawn.npy", path)
    out = tmp_path / "walk.npy"
    status, _, err = _run(["generate", "a person walks", "--trajectory",
                           f"pelvis={tmp_path / 'drawn.npy'}", "--camera", "1,20,45",
                           "--steps", "10", "--out", str(out)], capsys)
    assert status == 0, err
    q = cam.project(np.load(out))[:, 0]
    assert np.linalg.norm(q - path, axis=-1).mean() < 0.1


@pytest.mark.filterwarnings("ignore:the BVH reproduces the joints only")
def test_generate_from_a_saved_sketch(tmp_path, capsys):
    """The lesson-10 example sketch (JSON from the canvas): its action word and camera are
    used, and the clip's projected pelvis follows the drawn stroke."""
    from physlab.demos.sketch_to_motion import EXAMPLE_SKETCH
    from physlab.motion.sketch import Sketch

    out = tmp_path / "walk.npy"
    status, printed, err = _run(["generate", "--sketch", str(EXAMPLE_SKETCH), "--steps", "10",
                                 "--out", str(out)], capsys)
    assert status == 0, err
    assert "'a person walks'" in printed
    cond = Sketch.load(EXAMPLE_SKETCH).conditions()
    q = cond["camera"].project(np.load(out))[:, 0]
    assert np.linalg.norm(q - cond["trajectories_2d"]["pelvis"], axis=-1).mean() < 0.05


@pytest.mark.parametrize("args, match", [
    (["generate", "--out", "x.bvh"], "give the action text"),
    (["generate", "a person walks", "--sketch", "none.json", "--out", "x.bvh"],
     "--sketch none.json: no such file"),
    (["generate", "a person walks", "--out", "x.avi"], "cannot write .avi"),
    (["generate", "a person walks", "--camera", "1,20", "--out", "x.bvh"],
     "expected SCALE,PITCH,YAW"),
    (["generate", "a person walks", "--trajectory", "pelvis", "--out", "x.bvh"],
     "expected JOINT=FILE"),
    (["generate", "a person walks", "--trajectory", "tail=/nonexistent.npy", "--out", "x.bvh"],
     "no such file"),
    (["generate", "", "--out", "x.bvh"], "action must be a non-empty text"),
    (["train", "motion", "--steps", "-5", "--out", "m.pt"], "steps must be >= 1"),
    (["evaluate", "motion", "--control", "none.pt", "--windows", "1"], "none.pt"),
    # a bad argument of each subcommand: one `physlab: error:` line, exit code 2
    (["lessons", "01"], "unrecognized arguments: 01"),
    (["execute", "missing.ipynb"], "no notebook at missing.ipynb"),
    (["reproduce", "--lessons", "99"], "no lesson matches ['99']"),
    (["animate", "--fps", "0", "--out", "a.gif"], "--fps must be in 1..120, got 0"),
    (["animate", "--out", "a.png"], "cannot write .png"),
    (["animate", "--duration", "soon"], "argument --duration: invalid float value"),
    (["inbetween", "k0.png", "k1.png", "--skeleton0", "s.json", "--skeleton1", "s.json",
      "--frames", "x", "--out", "o"], "argument --frames: invalid int value"),
    (["generate", "a person walks", "--steps", "many", "--out", "x.bvh"],
     "argument --steps: invalid int value"),
    (["train", "motion", "--steps", "x"], "invalid int value: 'x' (see physlab train motion"),
    (["train", "dog"], "argument what: invalid choice: 'dog'"),
    (["evaluate", "inbetween", "--size", "big"],
     "invalid int value: 'big' (see physlab evaluate inbetween --help)"),
    (["evaluate", "motion", "--windows", "x", "--control", "c.pt"],
     "invalid int value: 'x' (see physlab evaluate motion --help)"),
    (["evaluate", "motion"], "--control is required"),
])
def test_subcommand_errors_are_one_line(args, match, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, out, err = _run(args, capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and match in lines[0], err
    assert lines[0].startswith("physlab: error: ") and out == ""
