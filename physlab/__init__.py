"""physlab: physics-based and learning-based character animation, for teaching and reproduction."""
__version__ = "0.1.0"
