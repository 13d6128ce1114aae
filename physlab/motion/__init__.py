"""Motion: the 22-joint HumanML3D skeleton, BVH mocap files and (later) the Sketch2Anim
motion generator.

* :mod:`.skeleton` — :data:`JOINT_NAMES`, :data:`PARENTS`, :data:`KINEMATIC_CHAINS`,
  Euler angles and forward kinematics; joints arrays are ``(T, 22, 3)`` in metres, y up;
* :mod:`.bvh` — :func:`read_bvh` / :func:`write_bvh` and :func:`retarget_to_smpl22` with the
  joint mappings of the Bandai-Namco and CMU clips;
* :mod:`.features` — the redundant HumanML3D-style per-frame features (D = 137) with an exact
  inverse, canonicalisation and normalisation statistics;
* :mod:`.dataset` — Bandai-Namco clips (cached), action texts, 40-frame training windows,
  Sketch2Anim's keypose + trajectory conditions (Sec. 3), the held-out split by take;
* :mod:`.metrics` — foot-skating ratio (GMD), MPJPE, trajectory error, jerk (AUJ, PJ);
* :mod:`.camera` — Sketch2Anim's storyboard :class:`Camera` (orthographic ``P(x, v)``,
  normalised image coordinates, pixels) and the sketch augmentations of supp. B;
* :mod:`.export` — :func:`joints_to_bvh`, generated joint positions → BVH (Blender);
* :mod:`.text` — the offline action-word encoder (all-MiniLM-L6-v2, CLIP's stand-in) and
  its embedding cache (loads the model only when encoding); :mod:`.minilm` — the
  encoder's forward pass in plain PyTorch;
* :mod:`.diffusion` — the noise scheduler (DDPM / DDIM, classifier-free guidance); imports
  torch, so it is not imported here;
* :mod:`.transitions` — model-free transitions between clips (linear, slerp, SQUAD);
* :mod:`.blend` — placing clips one after another and joining them, Sketch2Anim's
  DDIM-inversion blending (supp. D) and the baselines; :mod:`.storyboard` —
  :class:`Storyboard` frames to one animation (:func:`storyboard_to_motion`);
* :mod:`.sampling` — :func:`generate` and :class:`Generator` (trained checkpoint -> motion);
  ``from physlab.motion import generate`` gives the *function* (DESIGN.md), loaded on first
  use so that importing this package never imports torch.

Importing this package is cheap and never imports torch: modules that need torch import it
themselves and are not imported here.
"""
from .bvh import (BANDAI_NAMCO_MAPPING, CMU_MAPPING, CMU_MAX_MAPPING, CMU_SCALE, BVHMotion,
                  SMPL22Mapping, read_bvh, resample_local, retarget_to_smpl22, write_bvh)
from . import metrics, text
from .camera import Camera
from .export import joints_to_bvh
from .storyboard import Storyboard, StoryboardAnimation, StoryboardFrame, animate_storyboard, storyboard_to_motion
from .dataset import (TRAJECTORY_JOINT_NAMES, TRAJECTORY_JOINTS, Condition, MotionClip, Windows,
                      action_text, condition_from_window, load_clips, make_windows,
                      split_by_take)
from .features import FEATURE_DIM, FeatureStats, canonicalize, features_to_joints, joints_to_features
from .skeleton import (FOOT_JOINTS, JOINT_NAMES, KINEMATIC_CHAINS, PARENTS, bone_lengths,
                       euler_to_matrix, forward_kinematics, joint_index, topological_order)

__all__ = [
    "JOINT_NAMES", "PARENTS", "KINEMATIC_CHAINS", "FOOT_JOINTS", "joint_index", "bone_lengths",
    "euler_to_matrix", "forward_kinematics", "topological_order", "BVHMotion", "read_bvh",
    "write_bvh", "resample_local", "SMPL22Mapping", "retarget_to_smpl22",
    "BANDAI_NAMCO_MAPPING", "CMU_MAPPING", "CMU_MAX_MAPPING", "CMU_SCALE",
    "FEATURE_DIM", "FeatureStats", "canonicalize", "joints_to_features", "features_to_joints",
    "TRAJECTORY_JOINTS", "TRAJECTORY_JOINT_NAMES", "MotionClip", "Windows", "Condition",
    "load_clips", "action_text", "make_windows", "condition_from_window", "split_by_take",
    "metrics", "text", "joints_to_bvh", "Camera", "Storyboard", "StoryboardFrame",
    "StoryboardAnimation", "storyboard_to_motion", "animate_storyboard",
    "generate", "Generator", "load_generator", "build_condition", "DEFAULT_CHECKPOINT",
]

#: Names served lazily from :mod:`.sampling` (its import chain needs torch only when a
#: model is built, but keeping it out of ``import physlab.motion`` keeps that import cheap).
_SAMPLING = ("generate", "Generator", "load_generator", "build_condition", "DEFAULT_CHECKPOINT")


def __getattr__(name):
    if name in _SAMPLING:
        from . import sampling
        return getattr(sampling, name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


def __dir__():
    return sorted(set(globals()) | set(_SAMPLING))
