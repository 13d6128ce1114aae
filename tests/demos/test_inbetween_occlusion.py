"""Lesson 07's demo helpers (the algorithms are tested in tests/inbetween/test_occlusion.py)."""
import numpy as np
import pytest

from physlab.demos import inbetween_occlusion as demo
from physlab.mesh import boundary_polygon


def test_shifted_t_junctions_move_along_the_outline():
    pair, k0, k1, o0, o1 = demo.occluded_pair("fold_arm", 128)
    occ = o1[0]
    moved = demo.shifted_t_junctions(occ, 6.0)
    P = boundary_polygon(occ.mask, epsilon=0.5)
    # still on the outline, and about 6 px away from where they were (arc ≥ chord)
    A, B = P, np.roll(P, -1, axis=0)
    for q in moved.t_junctions:
        t = np.clip(np.einsum("ij,ij->i", q - A, B - A) / np.einsum("ij,ij->i", B - A, B - A), 0, 1)
        assert np.linalg.norm(A + t[:, None] * (B - A) - q, axis=1).min() < 1e-6
    d = np.linalg.norm(moved.t_junctions - occ.t_junctions, axis=1)
    assert np.all((d > 2.0) & (d < 6.5))
    assert np.allclose(demo.shifted_t_junctions(occ, 0.0).t_junctions, occ.t_junctions, atol=1.0)


def test_switching_rule_figure_reports_the_count():
    fig = demo.switching_rule_figure(10, (1, 4, 7), max_shown=4)
    title = fig._suptitle.get_text()
    assert "14 valid assignments (formula 14)" in title and "first 4 shown" in title


def test_occluded_pair_rejects_unknown_names():
    with pytest.raises(ValueError, match="fold_arm"):
        demo.occluded_pair("moonwalk")


def test_t_junction_demo_reports_bad_annotations_in_the_figure():
    fig = demo.t_junction_demo(shift=0.0, size=96)
    texts = [t.get_text() for ax in fig.axes for t in ax.texts]
    titles = [ax.get_title() for ax in fig.axes]
    assert not texts and any("assignments" in t for t in titles)


def test_three_layer_demo_and_figure():
    """Lesson 07's Fig. 9 section: the three runs, three layers winning over all in-betweens
    (measured at 160 px, 5 frames: PSNR 30.04 / 29.27 / 28.97 dB), and a figure whose first
    panel shows both hidden ranks."""
    from physlab.inbetween.evaluate import score_frames

    pair, truth, runs = demo.three_layers(160, n=5)
    assert list(runs) == ["three layers", "two layers", "one sheet"]
    assert [getattr(r.templates[1], "n_layers", 1) for r in runs.values()] == [3, 2, 1]
    s = {k: score_frames(r.frames, truth)["psnr_all"] for k, r in runs.items()}
    assert s["three layers"] > s["two layers"] + 0.3 and s["three layers"] > s["one sheet"] + 0.5
    fig = demo.three_layer_figure(pair, truth, runs)
    assert len(fig.axes) == 5 and len(fig.axes[0].collections) == 2   # ranks 1 and 2
    assert [a.get_title().split("\n")[0] for a in fig.axes[1:]] == ["truth"] + list(runs)


def test_tear_figure_draws_given_sequences_without_solving(monkeypatch):
    pair, k0, k1, o0, o1 = demo.occluded_pair("fold_arm", 96)
    t = np.linspace(1, 0, 3)
    frames = list(pair.ground_truth(t))
    seq = (t, frames, frames, [4.0, 5.25, 9.5], [4.0, 4.125, 4.5], ("single", "layered"))

    def no_solve(*a, **k):
        raise AssertionError("tear_figure solved the deformations although they were given")

    monkeypatch.setattr(demo, "tear_sequences", no_solve)
    fig, tpls = demo.tear_figure(pair, k1, o1, n=3, sequences=seq)
    titles = [ax.get_title() for ax in fig.axes]
    assert tpls == ("single", "layered")
    assert "E_d = 9.50" in titles and "E_d = 4.50" in titles      # the given energies, drawn
    with pytest.raises(ValueError, match="n = 4"):
        demo.tear_figure(pair, k1, o1, n=4, sequences=seq)
