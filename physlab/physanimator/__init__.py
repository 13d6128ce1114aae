"""PhysAnimator, physics part (supplementary Eqs. 1–10): a drawing becomes a physically
animated cartoon.

* :mod:`.flow` — wind / repel / attract flow particles (Eqs. 8–9);
* :mod:`.strokes` — energy strokes that carry flow particles along a drawn polyline;
* :mod:`.rigging` — fixed regions and wavy rigging points (Eq. 10);
* :mod:`.collisions` — ground, walls and body–body contacts;
* :mod:`.scene` — materials, bodies, the scene and its JSON form;
* :mod:`.simulation` — semi-implicit Euler (Eq. 7) of the Fixed Corotated FEM bodies.

The paper's final stage renders frames with a sketch-guided video diffusion model
(ToonCrafter + ControlNet); its weights are not available offline, so physlab renders by
warping the drawing with the simulated mesh (:mod:`physlab.render`) and also produces the
per-frame control images such a model would consume.
"""
from .collisions import max_penetration, resolve_body_contacts, resolve_half_planes
from .flow import FLOW_KINDS, attract_force, flow_force, repel_force, wind_force
from .rigging import FixedRig, WavyRig, wavy_rig_position
from .scene import Body, Material, Scene
from .simulation import (Animation, SceneSystem, UnstableTimeStep, measured_stable_dt,
                         safe_time_step, simulate)
from .strokes import EnergyStroke

__all__ = [
    "wind_force", "repel_force", "attract_force", "flow_force", "FLOW_KINDS", "EnergyStroke",
    "FixedRig", "WavyRig", "wavy_rig_position", "Material", "Body", "Scene", "simulate",
    "Animation", "SceneSystem", "UnstableTimeStep", "safe_time_step", "resolve_half_planes",
    "resolve_body_contacts", "max_penetration", "measured_stable_dt",
]
