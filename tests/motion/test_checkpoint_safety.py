"""Loading a checkpoint never runs code from it (Sketch2Anim generator, physlab.motion.checkpoint).

A crafted ``.pt`` file whose pickle would create a marker file is passed to every entry point
that reads checkpoints: the marker must not appear and the error must name the file."""
import pickle

import numpy as np
import pytest
import torch

from physlab.motion import generate
from physlab.motion.sampling import Generator
from physlab.motion.checkpoint import (CHECKPOINT_KIND, CHECKPOINT_VERSION, _from_safe,
                                       _to_safe, load_checkpoint, save_checkpoint)
from physlab.motion.train import train


class _Payload:
    """Unpickling this calls ``open(marker, "w")``: a file appears if the pickle is run."""

    def __init__(self, marker):
        self.marker = str(marker)

    def __reduce__(self):
        return (open, (self.marker, "w"))


@pytest.fixture
def evil(tmp_path):
    marker = tmp_path / "PWNED"
    path = tmp_path / "evil.pt"
    torch.save({"kind": CHECKPOINT_KIND, "version": CHECKPOINT_VERSION,
                "model": {"w": torch.zeros(2)}, "x": _Payload(marker)}, path)
    with open(path, "rb") as f:                       # the payload really is in the file
        assert b"PWNED" in f.read()
    return path, marker


@pytest.mark.parametrize("entry", ["load_checkpoint", "Generator.from_checkpoint", "generate",
                                   "train --resume"])
def test_a_malicious_pickle_is_refused_not_run(evil, entry, tmp_path):
    path, marker = evil
    calls = {
        "load_checkpoint": lambda: load_checkpoint(path),
        "Generator.from_checkpoint": lambda: Generator.from_checkpoint(path),
        "generate": lambda: generate("a person walks", checkpoint=path, steps=2),
        "train --resume": lambda: train(stage="base", out=str(path), resume=True, smoke=True,
                                        progress=False, steps=1, data_root=str(tmp_path)),
    }
    with pytest.raises(ValueError, match=r"evil\.pt was refused: it holds Python objects"):
        calls[entry]()
    assert not marker.exists(), f"{entry} executed the pickle payload"


def test_numpy_state_round_trips_through_the_safe_format(tmp_path):
    state = {"kind": CHECKPOINT_KIND, "version": CHECKPOINT_VERSION,
             "model": {"w": torch.arange(3.0)},
             "feature_stats": {"mean": np.linspace(0, 1, 5), "std": np.ones(5, np.float32)},
             "text_cache": {"texts": np.array(["a person walks", "a person runs"]),
                            "encoder_name": np.array("minilm")},
             "rng": [{"numpy": np.random.default_rng(7).bit_generator.state,
                      "torch": torch.get_rng_state()}],
             "scalar": np.float64(2.5)}
    path = save_checkpoint(tmp_path / "ok.pt", state)
    torch.load(path, weights_only=True)                       # loadable without unpickling code
    back = load_checkpoint(path)
    assert np.array_equal(back["feature_stats"]["mean"], state["feature_stats"]["mean"])
    assert back["feature_stats"]["std"].dtype == np.float32
    assert list(back["text_cache"]["texts"]) == ["a person walks", "a person runs"]
    assert str(back["text_cache"]["encoder_name"]) == "minilm"
    assert back["rng"][0]["numpy"] == state["rng"][0]["numpy"]
    assert back["scalar"] == 2.5 and isinstance(back["scalar"], float)
    rng = np.random.default_rng(0)
    rng.bit_generator.state = back["rng"][0]["numpy"]         # restores the generator
    assert rng.random() == np.random.default_rng(7).random()
    assert _from_safe(_to_safe({"a": (1, 2)})) == {"a": [1, 2]}


@pytest.mark.parametrize("bad", [float("nan"), float("inf")])
def test_non_finite_weights_are_named(tmp_path, bad):
    w = torch.zeros(3)
    w[1] = bad
    path = save_checkpoint(tmp_path / "nan.pt", {"kind": CHECKPOINT_KIND,
                                                 "version": CHECKPOINT_VERSION,
                                                 "model": {"layer.weight": w}})
    with pytest.raises(ValueError, match=r"non-finite weights .* in 'layer\.weight'"):
        load_checkpoint(path)


def test_an_old_format_checkpoint_gets_a_clear_error(tmp_path):
    path = tmp_path / "v1.pt"
    torch.save({"kind": CHECKPOINT_KIND, "version": 1, "model": {},
                "feature_stats": {"mean": np.zeros(2)}}, path)     # numpy inside: format 1
    with pytest.raises(ValueError, match=r"v1\.pt was refused.*retrain it"):
        load_checkpoint(path)
    with pytest.raises(pickle.UnpicklingError):                   # what torch itself says
        torch.load(path, weights_only=True)
