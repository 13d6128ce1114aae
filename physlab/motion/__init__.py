"""Motion: the 22-joint HumanML3D skeleton, BVH mocap files and (later) the Sketch2Anim
motion generator.

* :mod:`.skeleton` — :data:`JOINT_NAMES`, :data:`PARENTS`, :data:`KINEMATIC_CHAINS`,
  Euler angles and forward kinematics; joints arrays are ``(T, 22, 3)`` in metres, y up;
* :mod:`.bvh` — :func:`read_bvh` / :func:`write_bvh` and :func:`retarget_to_smpl22` with the
  joint mappings of the Bandai-Namco and CMU clips.

Importing this package is cheap and never imports torch: modules that need torch import it
themselves and are not imported here.
"""
from .bvh import (BANDAI_NAMCO_MAPPING, CMU_MAPPING, CMU_MAX_MAPPING, CMU_SCALE, BVHMotion,
                  SMPL22Mapping, read_bvh, resample_local, retarget_to_smpl22, write_bvh)
from .skeleton import (FOOT_JOINTS, JOINT_NAMES, KINEMATIC_CHAINS, PARENTS, bone_lengths,
                       euler_to_matrix, forward_kinematics, joint_index, topological_order)

__all__ = [
    "JOINT_NAMES", "PARENTS", "KINEMATIC_CHAINS", "FOOT_JOINTS", "joint_index", "bone_lengths",
    "euler_to_matrix", "forward_kinematics", "topological_order", "BVHMotion", "read_bvh",
    "write_bvh", "resample_local", "SMPL22Mapping", "retarget_to_smpl22",
    "BANDAI_NAMCO_MAPPING", "CMU_MAPPING", "CMU_MAX_MAPPING", "CMU_SCALE",
]
