"""Continuous collision detection of moving (rational) Bézier patches (Chen et al. 2024)."""
from .ellipsoid import ellipsoid_patches
from .primitives import Patch, subdivision_matrices
from .queries import edge_edge, load_queries, vertex_face
from .solver import PatchContact, SearchStats, contact_manifold, first_contact

__all__ = ["Patch", "PatchContact", "SearchStats", "contact_manifold", "edge_edge",
           "ellipsoid_patches", "first_contact", "load_queries", "subdivision_matrices",
           "vertex_face"]
