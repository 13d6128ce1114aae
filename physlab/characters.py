"""Deprecated: moved to :mod:`physlab.inbetween.characters` (next to the skeleton it draws).

``import physlab.characters`` keeps working for one release and warns."""
import warnings

from physlab.inbetween.characters import *  # noqa: F401,F403
from physlab.inbetween.characters import __all__  # noqa: F401

warnings.warn("physlab.characters moved to physlab.inbetween.characters (also re-exported by "
              "physlab.inbetween); the old module goes in the next release",
              DeprecationWarning, stacklevel=2)
