"""Skeleton-driven inbetweening of bitmap drawings (Brodt & Bessmeltsev 2024).

Modules: :mod:`.skeleton` (2D skeletons, bone-angle interpolation), :mod:`.template`
(mask → Triangle mesh with handle vertices), :mod:`.deform` (symmetric Dirichlet energy,
Sobolev-preconditioned quasi-Newton with injectivity line search), :mod:`.skinning` (LBS with
bounded biharmonic weights, ARAP: comparisons), :mod:`.frame_interpolation` (optical-flow frame
interpolation, the RIFE stand-in), :mod:`.blend` (image matrix, blending costs, Dijkstra
path), :mod:`.metrics` (PSNR, SSIM, Chamfer), :mod:`.baselines`, :mod:`.retarget` (BVH →
drawing skeletons), :mod:`.pipeline` (:func:`inbetween`).
"""
from .deform import (SymmetricDirichletDeformer, deform, symmetric_dirichlet_energy,
                     symmetric_dirichlet_gradient)
from .pipeline import InbetweenResult, inbetween
from .skeleton import Skeleton, check_compatible, interpolate
from .template import Template, build_template

__all__ = ["Skeleton", "check_compatible", "interpolate", "Template", "build_template",
           "SymmetricDirichletDeformer", "deform", "symmetric_dirichlet_energy",
           "symmetric_dirichlet_gradient", "inbetween", "InbetweenResult"]
