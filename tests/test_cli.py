"""physlab.cli: listing lessons and the headless `reproduce` command."""
import pytest

from physlab import cli


def test_lesson_paths_selection():
    all_paths = cli.lesson_paths()
    assert [p.name[:2] for p in all_paths] == sorted(p.name[:2] for p in all_paths)
    assert [p.name[:2] for p in cli.lesson_paths(["1"])] == ["01"]
    with pytest.raises(ValueError, match="available"):
        cli.lesson_paths(["99"])


def test_reproduce_and_execute_take_a_cell_timeout(tmp_path, monkeypatch, capsys):
    seen = []
    monkeypatch.setattr(cli, "execute_notebook",
                        lambda path, timeout=600, cwd=None: seen.append(timeout) or {"cells": []})
    monkeypatch.setattr(cli, "save_figures", lambda nb, out_dir: [])
    assert cli.main(["reproduce", "--lessons", "01", "--out", str(tmp_path), "--timeout",
                     "42"]) == 0
    assert cli.main(["reproduce", "--lessons", "01", "--out", str(tmp_path)]) == 0
    assert seen == [42, 600]
    for cmd in (["reproduce", "--lessons", "01"], ["execute", "lessons/x.ipynb"]):
        assert cli.main(cmd + ["--timeout", "0"]) == 2
        err = capsys.readouterr().err
        assert "--timeout must be a positive number of seconds per cell, got 0" in err
    assert seen == [42, 600]                    # bad timeouts stop before any kernel starts


@pytest.mark.slow
@pytest.mark.xdist_group("nbclient_kernel")       # see tests/test_viz.py
def test_reproduce_writes_the_lesson_figures(tmp_path):
    cli.main(["reproduce", "--lessons", "01", "--out", str(tmp_path)])
    pngs = sorted((tmp_path / "01_odes_and_explicit_euler").glob("*.png"))
    assert len(pngs) >= 2
    import imageio.v3 as iio
    import numpy as np

    for p in pngs:
        im = iio.imread(p)
        assert im.shape[1] > 200 and im.shape[0] > 150
        assert len(np.unique(im[..., :3].mean(-1))) > 20  # not a blank canvas
