"""Fuzzing ``Scene.from_json``: a mutated scene file either loads as a valid :class:`Scene` or
raises ValueError / TypeError / FileNotFoundError whose message names the file (or "scene
JSON" for text) and the field — never KeyError, AttributeError, IndexError, ... and never a
scene with non-finite or out-of-range parameters."""
import copy
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from physlab import physanimator as pa
from physlab.mesh import grid_mesh

DELETE = object()


def _good_scene():
    texture = np.zeros((4, 4, 4), np.uint8)
    texture[1:3, 1:3] = (200, 40, 40, 255)
    return pa.Scene(
        [pa.Body(grid_mesh(3, 3, 30.0, 30.0), pa.Material(E=1e5, nu=0.3, rho=1.0),
                 texture=texture, offset=(10.0, 20.0), velocity=(1.0, 0.0), name="box"),
         pa.Body(grid_mesh(2, 2, 20.0, 20.0), offset=(60.0, 20.0), name="lid")],
        strokes=[pa.EnergyStroke([[0.0, 0.0], [20.0, 5.0], [40.0, 0.0]], "wind", n_particles=2,
                                 direction=(1.0, 0.0))],
        rigs=[pa.FixedRig(center=(10.0, 20.0), radius=5.0),
              pa.WavyRig(body=1, vertices=(3,), amplitude=4.0)],
        gravity=(0.0, 980.0), ground=200.0, walls=(0.0, 300.0))


GOOD = json.loads(_good_scene().to_json())


def _leaves(obj, path=()):
    """Paths to every dict value and list item (number lists: their first two items)."""
    out = [path] if path else []
    if isinstance(obj, dict):
        for k, v in obj.items():
            out += _leaves(v, path + (k,))
    elif isinstance(obj, list):
        for i, v in enumerate(obj[:2]):
            out += _leaves(v, path + (i,))
    return out


def _get(obj, path):
    for k in path:
        obj = obj[k]
    return obj


PATHS = _leaves(GOOD)
CONTAINERS = [()] + [p for p in PATHS if isinstance(_get(GOOD, p), dict)]
VALUES = st.one_of(
    st.none(), st.booleans(), st.integers(-3, 20), st.integers(-10**30, 10**30),
    st.floats(allow_nan=True, allow_infinity=True), st.text(max_size=4),
    st.sampled_from(["wind", "storm", "FixedRig", "WavyRig", "Spring", "", "{"]),
    st.lists(st.floats(-50, 50), max_size=3), st.lists(st.integers(-2, 20), max_size=4),
    st.lists(st.lists(st.floats(-5, 5), max_size=3), max_size=3),
    st.dictionaries(st.text(max_size=3), st.integers(), max_size=2))
EDIT = st.one_of(
    st.tuples(st.just("set"), st.sampled_from(PATHS), st.one_of(st.just(DELETE), VALUES)),
    st.tuples(st.just("add"), st.sampled_from(CONTAINERS), st.text(min_size=1, max_size=5)))


def _apply(d, edits):
    for op, path, value in edits:
        try:
            if op == "add":
                _get(d, path)[value] = 1.0
            elif value is DELETE:
                del _get(d, path[:-1])[path[-1]]
            else:
                _get(d, path[:-1])[path[-1]] = value
        except (KeyError, IndexError, TypeError):
            pass                                  # an earlier edit removed or replaced the parent
    return d


def _check_outcome(load, source):
    try:
        scene = load()
    except (ValueError, TypeError, FileNotFoundError) as e:
        msg = str(e)
        assert msg.startswith(source + ": "), msg
        assert ("field " in msg or "not valid JSON" in msg or "not a text file" in msg), msg
        return None
    assert isinstance(scene, pa.Scene)
    assert all(np.isfinite(v) for v in (scene.friction, scene.restitution, scene.damping))
    assert 0 <= scene.restitution <= 1 and scene.friction >= 0 and scene.damping >= 0
    assert np.all(np.isfinite(scene.gravity))
    for b in scene.bodies:
        assert np.all(np.isfinite(b.mesh.X)) and b.material.E > 0 and -1 < b.material.nu < 0.5
    for s in scene.strokes:
        assert np.all(np.isfinite(s.points)) and s.range > 0 and np.isfinite(s.strength)
    return scene


SETTINGS = settings(max_examples=200, deadline=None, derandomize=True,
                    suppress_health_check=[HealthCheck.too_slow])


@SETTINGS
@given(st.lists(EDIT, min_size=1, max_size=4))
def test_mutated_scene_json_gives_a_scene_or_a_clear_error(edits):
    text = json.dumps(_apply(copy.deepcopy(GOOD), edits))
    _check_outcome(lambda: pa.Scene.from_json(text), "scene JSON")


@SETTINGS
@given(st.lists(EDIT, max_size=2), st.data())
def test_damaged_scene_files_name_the_file(edits, data):
    text = json.dumps(_apply(copy.deepcopy(GOOD), edits))
    damage = data.draw(st.sampled_from(["none", "truncate", "byte", "splice"]))
    raw = text.encode()
    if damage == "truncate":
        raw = raw[:data.draw(st.integers(0, len(raw) - 1))]
    elif damage == "byte":
        i = data.draw(st.integers(0, len(raw) - 1))
        raw = raw[:i] + bytes([data.draw(st.integers(0, 255))]) + raw[i + 1:]
    elif damage == "splice":
        i = data.draw(st.integers(0, len(raw)))
        raw = raw[:i] + data.draw(st.sampled_from([b"}", b"]", b",", b'"', b"NaN", b"\xff"])) \
            + raw[i:]
    with tempfile.TemporaryDirectory() as tmp:
        path = Path(tmp) / "scene.json"
        path.write_bytes(raw)
        _check_outcome(lambda: pa.Scene.from_json(path), str(path))
        _check_outcome(lambda: pa.Scene.from_json(str(path)), str(path))


def test_the_unmutated_scene_round_trips_and_simulates():
    scene = _check_outcome(lambda: pa.Scene.from_json(json.dumps(GOOD)), "scene JSON")
    assert json.loads(scene.to_json()) == GOOD
    anim = pa.simulate(scene, 0.02, dt=1e-3, fps=100, progress=False)
    assert anim.n_frames == 3 and all(np.all(np.isfinite(x)) for x in anim.x)


@pytest.mark.parametrize("field, value, match", [
    (("friction",), float("nan"), r"field scene: friction must be finite"),
    (("rigs", 1, "vertices"), [99], r"field rigs\[1\] \(on body 1, 'lid'\): rig vertex 99 "
                                    r"is outside 0\.\.8"),
    (("rigs", 0, "center"), [900.0, 900.0], r"field rigs\[0\] .*selects no vertex"),
    (("rigs", 0, "body"), 2, r"field rigs\[0\] refers to body 2, but the scene has 2"),
    (("strokes", 0, "points", 1), [float("nan"), 1.0], r"field strokes\[0\]: stroke points "
                                                       r"must be finite, point 1"),
    (("bodies", 1, "material", "nu"), 0.5, r"field bodies\[1\]: Material nu"),
    (("bodies",), {}, r"field bodies must be a JSON list, got dict"),
])
def test_fuzzer_findings_stay_fixed(field, value, match):
    d = copy.deepcopy(GOOD)
    _get(d, field[:-1])[field[-1]] = value
    with pytest.raises(ValueError, match=r"^scene JSON: " + match):
        pa.Scene.from_json(json.dumps(d))
