"""Skeleton-driven inbetweening of bitmap drawings (Brodt & Bessmeltsev 2024).

Modules: :mod:`.skeleton` (2D skeletons, their interpolation between keys), :mod:`.template`
(mask → Triangle mesh with handle vertices), :mod:`.deform` (symmetric Dirichlet energy,
Sobolev-preconditioned quasi-Newton with injectivity line search), :mod:`.skinning` (LBS with
bounded biharmonic weights, ARAP: comparisons), :mod:`.frame_interpolation` (optical-flow frame
interpolation, the RIFE stand-in), :mod:`.blend` (image matrix, blending costs, Dijkstra
path), :mod:`.metrics` (PSNR, SSIM, Chamfer), :mod:`.baselines`, :mod:`.retarget` (BVH →
drawing skeletons), :mod:`.occlusion` (occlusion regions, T-junctions, layered templates),
:mod:`.pipeline` (:func:`inbetween`), :mod:`.characters` (procedural cartoon characters with
ground-truth in-betweens, the benchmarks), :mod:`.cutout` (a drawing cut into rigid body
parts and posed as a paper doll: the second ground truth of the occluded real drawings).
"""
from .characters import (ADJACENT_PARTS, CHARACTER_JOINTS, CHARACTER_PARTS, CHARACTER_STYLES,
                         PAINT_ORDER, InbetweenPair, character_occlusions, character_part_labels,
                         character_layered_occlusions, character_skeleton,
                         inbetween_benchmark, occlusion_benchmark,
                         occlusion_benchmark_three_layers, paint_order, part_overlaps, pose_character, render_character)
from .cutout import CutoutParts, render_cutout, segment_parts
from .deform import (SymmetricDirichletDeformer, deform, symmetric_dirichlet_energy,
                     symmetric_dirichlet_gradient)
from .occlusion import (LayeredTemplate, Occlusion, build_layered_template, load_occlusions,
                        save_occlusions, suggest_occlusions, suggest_t_junctions)
from .pipeline import InbetweenResult, inbetween
from .skeleton import INTERPOLATION_METHODS, Skeleton, check_compatible, interpolate
from .template import Template, build_template

__all__ = ["Skeleton", "check_compatible", "interpolate", "INTERPOLATION_METHODS", "Template",
           "build_template", "SymmetricDirichletDeformer", "deform", "symmetric_dirichlet_energy",
           "symmetric_dirichlet_gradient", "inbetween", "InbetweenResult",
           "CHARACTER_STYLES", "CHARACTER_JOINTS", "CHARACTER_PARTS", "ADJACENT_PARTS",
           "PAINT_ORDER", "character_skeleton", "pose_character", "render_character",
           "character_part_labels", "part_overlaps", "InbetweenPair", "inbetween_benchmark",
           "occlusion_benchmark", "occlusion_benchmark_three_layers", "character_occlusions",
           "character_layered_occlusions", "paint_order", "Occlusion",
           "LayeredTemplate", "build_layered_template", "suggest_occlusions", "save_occlusions",
           "load_occlusions", "suggest_t_junctions", "CutoutParts", "segment_parts",
           "render_cutout"]
