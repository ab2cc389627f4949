"""The one place footforge reads MJX state that MJX keeps private.

mujoco-mjx 3.17 keeps its "jax" implementation's contacts (`Data._impl.contact`), its contact
force helper (`mujoco.mjx._src.support.contact_force_dim`) and the heightfield collision bounds
(`Model._impl.geom_rbound_hfield`) out of its public API: `mjx.Data` has no contact field, and no
MJCF sensor MJX supports reads the per-contact normal force or the geoms of each contact
(MuJoCo Playground reads the same `_impl` contacts for its foot contacts). Everything else in
footforge goes through these functions; `tests/test_mjx_private.py` fails when MJX moves or
reshapes them, and `tests/test_layout.py` fails on private access anywhere else.
"""

from __future__ import annotations

import numpy as np


def contacts(data):
    """(geom pairs (ncon, 2), signed distances (ncon,), m) of an MJX data's contact slots (the
    "jax" implementation's fixed-size arrays; a slot with distance >= 0 is not touching)."""
    contact = data._impl.contact
    return contact.geom, contact.dist


def contact_normal_forces(mjx_model, data):
    """(normal force of each condim-3 contact slot (n,), N; the indices of those slots into
    contacts(data)'s arrays (n,)). Every robot contact in footforge's models has condim 3."""
    from mujoco.mjx._src import support

    force, index = support.contact_force_dim(mjx_model, data, 3)
    return force[:, 0], index


def heightfield_bounds(mjx_model) -> np.ndarray:
    """A copy of each geom's bounding radius for its heightfield collision subgrid, m (MJX's
    ModelJAX.geom_rbound_hfield: geom_rbound unless changed)."""
    return np.array(mjx_model._impl.geom_rbound_hfield, copy=True)


def with_heightfield_bounds(mjx_model, bounds: np.ndarray):
    """`mjx_model` with the heightfield subgrid bounds replaced (heightfield_bounds)."""
    return mjx_model.replace(_impl=mjx_model._impl.replace(geom_rbound_hfield=np.asarray(bounds)))
