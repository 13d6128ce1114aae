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
