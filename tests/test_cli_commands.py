"""Each `physlab` subcommand runs headless on tiny input (the library does the work; these
check the wiring, the files written and the one-line errors)."""
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


@pytest.mark.parametrize("cmd", ["animate", "inbetween", "generate", "train", "evaluate"])
def test_each_subcommand_help_shows_an_example(cmd, capsys):
    status, out, _ = _run([cmd, "--help"], capsys)
    assert status == 0 and "example" in out and f"physlab {cmd}" in out


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


@pytest.mark.parametrize("args, match", [
    (["generate", "a person walks", "--out", "x.avi"], "cannot write .avi"),
    (["generate", "a person walks", "--trajectory", "pelvis", "--out", "x.bvh"],
     "expected JOINT=FILE"),
    (["generate", "a person walks", "--trajectory", "tail=/nonexistent.npy", "--out", "x.bvh"],
     "no such file"),
    (["generate", "", "--out", "x.bvh"], "action must be a non-empty text"),
    (["train", "motion", "--steps", "-5", "--out", "m.pt"], "steps must be >= 1"),
    (["evaluate", "motion", "--control", "none.pt", "--windows", "1"], "none.pt"),
])
def test_subcommand_errors_are_one_line(args, match, tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    status, _, err = _run(args, capsys)
    lines = err.strip().splitlines()
    assert status == 2 and len(lines) == 1 and match in lines[0], err
