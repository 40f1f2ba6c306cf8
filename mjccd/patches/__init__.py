"""Continuous collision detection of moving (rational) Bézier patches (Chen et al. 2024)."""
from .primitives import Patch, subdivision_matrices
from .solver import PatchContact, SearchStats, contact_manifold, first_contact

__all__ = ["Patch", "PatchContact", "SearchStats", "contact_manifold", "first_contact",
           "subdivision_matrices"]
