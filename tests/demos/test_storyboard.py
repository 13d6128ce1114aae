"""Tests of physlab.demos.storyboard (lesson 11's figures and small table): they run, show
what they claim, and the numbers they print hold."""
import numpy as np
import pytest
import torch

from physlab.demos import storyboard as demo
from physlab.motion.blend import junction_acceleration_ratio, junction_step_ratio


@pytest.fixture(scope="module")
def joined():
    torch.set_num_threads(1)
    a, b, actions = demo.two_clips(seed=3)         # lesson 11's pair: the walk ends mid-stride
    return demo.join_methods(a, b, actions)


def test_join_methods_and_junction_figure(joined):
    assert set(joined) == {"concat", "linear", "squad", "inversion"}
    assert joined["concat"].joints.shape == (80, 22, 3)
    assert joined["inversion"].joints.shape == (100, 22, 3)
    ratios = {m: junction_step_ratio(r.joints, r.window if r.window.stop > r.window.start
                                     else r.transition, list(r.clips))
              for m, r in joined.items()}
    assert ratios["concat"] > max(ratios["linear"], ratios["inversion"])       # the pop
    # ... in metres: the cut's one-frame jump is the largest step anywhere near the junction,
    # over twice the largest step in any blend's gap (0.40 m against 0.06-0.07 m)
    cut = demo.step_curve(joined["concat"].joints)
    assert cut[39] == cut[30:50].max()
    for m in ("linear", "squad", "inversion"):
        gap = joined[m].transition
        assert cut[39] > 2 * demo.step_curve(joined[m].joints[gap]).max(), m
    acc = {m: junction_acceleration_ratio(r.joints, r.window if r.window.stop > r.window.start
                                          else r.transition, list(r.clips))
           for m, r in joined.items()}
    assert acc["concat"] > 2 and max(acc["linear"], acc["squad"], acc["inversion"]) < 1
    fig = demo.junction_figure(joined)
    ax0, ax1 = fig.axes
    assert len(ax0.lines) == 4 and ax1.get_yscale() == "log"
    # the cut's step curve peaks at the junction (frame -1 -> 0)
    x, y = ax0.lines[0].get_data()
    assert abs(x[np.argmax(y)] + 0.5) < 1e-9


def test_step_curve_by_hand():
    x = np.zeros((3, 22, 3))
    x[1, 5, 0], x[2, 5, 0] = 0.3, 0.3
    x[2, 7, 2] = 0.1
    assert np.allclose(demo.step_curve(x), [0.3, 0.1])


def test_blend_demo_and_table():
    fig = demo.blend_demo("linear", 10)
    assert "linear, 10 frames" in fig.axes[0].get_title()
    rows = demo.lesson_blending_table(methods=("linear", "inversion"))
    assert list(rows) == ["real", "linear", "inversion"]
    assert rows["real"]["MPJPE"] == 0.0
    assert rows["inversion"]["bones"] < 1e-3 < rows["linear"]["bones"]  # rigid vs. not
    assert rows["inversion"]["AUJ"] < rows["real"]["AUJ"]
    text = demo.format_rows(rows)
    assert text.count("\n") == 4 and "| inversion |" in text


def test_impact_figure():
    from physlab.motion.editing import impact_of_conditions

    seq = impact_of_conditions(steps=20)
    fig = demo.impact_figure(seq)
    assert len(fig.axes) == 4
    assert [ax.get_title() for ax in fig.axes][1] == "+ keypose"
