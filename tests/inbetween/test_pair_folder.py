"""Keyframe-pair folders (physlab.inbetween.pair_folder): the layout, frame times, bad input."""
import json

import imageio.v3 as iio
import numpy as np
import pytest

from physlab.inbetween import Occlusion, inbetween_benchmark
from physlab.inbetween.pair_folder import (DEFAULT_FRAMES, load_pair_folder, read_skeleton,
                                           skeleton_from_dict)

from _drawings import write_pair


@pytest.fixture
def folder(tmp_path):
    write_pair(tmp_path / "pair", gt=(0.5, 0.25))
    return tmp_path / "pair"


def test_load_reads_everything(folder):
    pf = load_pair_folder(folder)
    assert pf.name == "pair" and pf.key0.shape == (96, 96, 4) and pf.animation is None
    assert list(pf.truth) == [0.25, 0.5] and pf.truth_files[0.25] == "gt_0.25.png"
    assert pf.occlusions == (None, None)
    # frame count: 11 does not hold t = 0.25, 13 is the smallest count above 11 that does
    assert pf.n_frames() == 13
    assert list(pf.truth_frames(13)) == [3, 6]
    assert pf.n_frames(5) == 5 and list(pf.truth_frames(5)) == [1, 2]
    # the nearest counts that fit are 9 and 13 (the smaller is suggested)
    with pytest.raises(ValueError, match=r"gt_0\.25\.png: t = 0\.25 is not a frame time of "
                                         r"linspace\(0, 1, 11\) \(step 0\.1\); use 9 frames"):
        pf.n_frames(11)
    for bad in (2, 4.0, True):
        with pytest.raises(ValueError, match="n_frames must be an integer >= 3"):
            pf.n_frames(bad)


def test_times_match_as_written_and_defaults(tmp_path):
    write_pair(tmp_path / "p", gt=())
    pf = load_pair_folder(tmp_path / "p")
    assert pf.truth == {} and pf.n_frames() == DEFAULT_FRAMES and pf.truth_frames(7) == {}
    iio.imwrite(tmp_path / "p" / "gt_0.333.png", pf.key0)  # t = 1/3 written with 3 decimals
    pf = load_pair_folder(tmp_path / "p")
    assert pf.n_frames() == 13 and list(pf.truth_frames(4)) == [1]
    with pytest.raises(ValueError, match="not a frame time"):
        pf.truth_frames(5)  # 0.25, 0.5: 0.333 is neither
    (tmp_path / "p" / "gt_0.333.png").rename(tmp_path / "p" / "gt_0.33.png")
    with pytest.raises(ValueError, match=r"gt_0\.33\.png: t = 0\.33 is not a frame time of "
                                         r"linspace\(0, 1, 4\)"):
        load_pair_folder(tmp_path / "p").truth_frames(4)  # 0.0033 from 1/3: more than 0.001


def test_animation_sets_the_frame_count(tmp_path):
    pair = write_pair(tmp_path / "p", gt=(0.5,), animation=7)
    pf = load_pair_folder(tmp_path / "p")
    assert len(pf.animation) == 7 and pf.n_frames() == 7
    np.testing.assert_allclose(pf.animation[3].xy, pair.animation(7)[3].xy)
    with pytest.raises(ValueError, match=r"animation\.json has 7 skeletons but 5 frames"):
        pf.n_frames(5)


def _break(folder, what):
    """Spoil one file of a good folder the way a user might."""
    if what == "no key0":
        (folder / "key0.png").unlink()
    elif what == "no skeletons":
        (folder / "skeleton0.json").unlink()
        (folder / "skeleton1.json").unlink()
    elif what == "key sizes":
        iio.imwrite(folder / "key1.png", np.zeros((80, 96, 4), np.uint8))
    elif what == "skeleton fields":
        d = json.loads((folder / "skeleton1.json").read_text())
        d["parent"] = d.pop("parents")
        (folder / "skeleton1.json").write_text(json.dumps(d))
    elif what == "skeleton json":
        (folder / "skeleton0.json").write_text('{"names": ["a"], ')
    elif what == "joints outside":
        d = json.loads((folder / "skeleton0.json").read_text())
        d["xy"][3] = [150.0, 20.0]
        (folder / "skeleton0.json").write_text(json.dumps(d))
    elif what == "other joints":
        d = json.loads((folder / "skeleton1.json").read_text())
        d["names"][2] = "tail"
        (folder / "skeleton1.json").write_text(json.dumps(d))
    elif what == "gt size":
        iio.imwrite(folder / "gt_0.5.png", np.zeros((64, 64, 4), np.uint8))
    elif what == "gt name":
        iio.imwrite(folder / "gt_half.png", np.zeros((96, 96, 4), np.uint8))
    elif what == "gt at a key":
        iio.imwrite(folder / "gt_1.0.png", np.zeros((96, 96, 4), np.uint8))
    elif what == "gt not an image":
        (folder / "gt_0.75.png").write_text("not a png")
    elif what == "animation topology":
        d = json.loads((folder / "skeleton0.json").read_text())
        d["names"][1] = "spine"
        (folder / "animation.json").write_text(json.dumps([d] * 5))
    elif what == "animation type":
        (folder / "animation.json").write_text(json.dumps({"frames": 5}))


@pytest.mark.parametrize("what, exc, match", [
    ("no key0", FileNotFoundError, r"pair folder .*pair: missing key0\.png \(a pair folder "
                                   r"holds key0\.png, key1\.png"),
    ("no skeletons", FileNotFoundError, r"missing skeleton0\.json, skeleton1\.json"),
    ("key sizes", ValueError, r"key0\.png is 96x96 px but .*key1\.png is 96x80; the keys must "
                              r"have the same size"),
    ("skeleton fields", ValueError, r"skeleton1\.json: missing field\(s\) \['parents'\]; "
                                    r"unknown field\(s\) \['parent'\]"),
    ("skeleton json", ValueError, r"skeleton0\.json: not valid JSON"),
    ("joints outside", ValueError, r"skeleton0\.json: joint '.*' at \(150\.0, 20\.0\) lies "
                                   r"outside the 96x96 image"),
    ("other joints", ValueError, r"skeleton0\.json and .*skeleton1\.json have different joints"),
    ("gt size", ValueError, r"gt_0\.5\.png is 64x64 px but the keys are 96x96"),
    ("gt name", ValueError, r"gt_half\.png: a ground-truth file is named gt_<t>\.png"),
    ("gt at a key", ValueError, r"gt_1\.0\.png: .*strictly between 0 and 1"),
    ("gt not an image", ValueError, r"gt_0\.75\.png is not a readable image"),
    ("animation topology", ValueError, r"animation\.json\[0\] have different joints"),
    ("animation type", ValueError, r"animation\.json: must be a JSON list of skeleton dicts"),
])
def test_bad_folders_name_the_file_and_the_fault(folder, what, exc, match):
    _break(folder, what)
    with pytest.raises(exc, match=match):
        load_pair_folder(folder)


def test_missing_folder_and_file_instead_of_folder(tmp_path):
    with pytest.raises(FileNotFoundError, match="no such folder"):
        load_pair_folder(tmp_path / "nope")
    (tmp_path / "f.png").write_bytes(b"")
    with pytest.raises(NotADirectoryError, match="not a folder"):
        load_pair_folder(tmp_path / "f.png")


def test_occlusion_files_become_occlusions(folder):
    (folder / "occlusions0.json").write_text(json.dumps(
        {"occlusions": [{"polygon": [[10, 20], [30, 20], [20, 40]], "t_junctions": [[20, 20]],
                         "label": "arm/torso"}]}))
    pf = load_pair_folder(folder)
    assert pf.occlusions[1] is None and len(pf.occlusions[0]) == 1
    occ = pf.occlusions[0][0]
    assert isinstance(occ, Occlusion) and occ.label == "arm/torso"
    np.testing.assert_array_equal(occ.t_junctions, [[20.0, 20.0]])
    (folder / "occlusions1.json").write_text("[{")
    with pytest.raises(ValueError, match=r"occlusions1\.json: not valid JSON"):
        load_pair_folder(folder)
    (folder / "occlusions1.json").write_text(json.dumps([{"polygon": [[0, 0], [1, 1]]}]))
    with pytest.raises(ValueError, match=r"occlusions1\.json: occlusions\[0\]: .*>= 3"):
        load_pair_folder(folder)


def test_skeleton_round_trip_and_messages(tmp_path):
    pair = inbetween_benchmark(size=96)[0]
    d = pair.skeleton0.to_dict()
    sk = skeleton_from_dict(d)
    np.testing.assert_array_equal(sk.xy, pair.skeleton0.xy)
    assert sk.names == pair.skeleton0.names
    (tmp_path / "s.json").write_text(json.dumps(d))
    assert read_skeleton(tmp_path / "s.json").names == sk.names
    with pytest.raises(FileNotFoundError, match=r"--skeleton0 .*none\.json: no such file"):
        read_skeleton(tmp_path / "none.json", "--skeleton0")
    with pytest.raises(ValueError, match=r"where: a skeleton must be a JSON object"):
        skeleton_from_dict([1, 2], "where")
    with pytest.raises(ValueError, match=r"s: xy must have shape \(16, 2\)"):
        skeleton_from_dict({**d, "xy": d["xy"][:-1]}, "s")
    depth = np.arange(16.0)
    np.testing.assert_array_equal(skeleton_from_dict({**d, "depth": depth.tolist()}).depth, depth)
    assert skeleton_from_dict({**d, "depth": None}).depth is None
