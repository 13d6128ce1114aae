"""The measurement scripts in scripts/ that the README cites: they run and refuse bad input."""
import importlib.util
from pathlib import Path

import pytest

SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"


def _load(name):
    spec = importlib.util.spec_from_file_location(name, SCRIPTS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_storyboard_seams_prints_one_row_per_method_and_seed(capsys):
    seams = _load("storyboard_seams")
    seams.main(["concat", "linear", "--seeds", "1"])
    rows = [r for r in capsys.readouterr().out.splitlines()[1:] if r.strip()]
    assert [r.split(" |")[0] for r in rows] == ["concat 0", "linear 0"]
    cut, linear = ([float(v) for v in r.split("|")[1].split()] for r in rows)
    assert len(cut) == len(linear) == 2                      # two junctions in three frames
    assert max(cut) > max(linear)                            # a plain cut jerks most
    assert float(rows[1].split("|")[3]) > 0.005              # linear blends shrink bones
    assert float(rows[0].split("|")[3]) < 1e-3               # one skeleton throughout


@pytest.mark.parametrize("argv, match", [(["wobble"], "unknown join method 'wobble'"),
                                         (["--seeds", "0"], "--seeds must be >= 1")])
def test_storyboard_seams_refuses_bad_input(argv, match, capsys):
    with pytest.raises(SystemExit):
        _load("storyboard_seams").main(argv)
    assert match in capsys.readouterr().err


def test_expert_denoisers_switches_network_at_the_level(real_data, tmp_path):
    """T_S = -1 samples with HI alone, 999 with LO alone, a level between mixes them."""
    import numpy as np
    import torch

    from physlab.motion.sampling import Generator
    from physlab.motion.train import train

    smoke = {"smoke": True, "progress": False, "steps": 2, "num_threads": 1}
    lo = train(stage="base", out=str(tmp_path / "lo.pt"), **smoke)["path"]
    hi = train(stage="base", out=str(tmp_path / "hi.pt"), skip=True, skip_pelvis=False, seed=1,
               **smoke)["path"]
    torch.set_num_threads(1)
    experts = _load("expert_denoisers")
    text = Generator.from_checkpoint(lo).text_cache.texts[0]
    own = {k: Generator.from_checkpoint(p)(text, seed=2, steps=6) for k, p in (("hi", hi),
                                                                               ("lo", lo))}
    got = {ts: experts.switched_generator(hi, lo, ts)(text, seed=2, steps=6)
           for ts in (-1, 500, 999)}
    np.testing.assert_array_equal(got[-1], own["hi"])
    np.testing.assert_array_equal(got[999], own["lo"])
    assert not np.array_equal(got[500], own["hi"]) and not np.array_equal(got[500], own["lo"])


def test_expert_denoisers_refuses_bad_input(capsys):
    with pytest.raises(SystemExit):
        _load("expert_denoisers").main(["a.pt", "b.pt", "1000"])
    assert "T_S must be in -1..999" in capsys.readouterr().err
