"""An independent reference for systems of rigid bodies: trees in reduced (joint) coordinates
with their own recursive dynamics, integrated by DOP853 with an error estimate, and the exact
motions of multibody systems that have closed forms.

This subpackage shares nothing with ``director_model`` (it does not import it): the director
form keeps twelve coordinates per body, a constant mass matrix and the joints as constraints;
this one has joint coordinates (quaternions for spherical joints, angles for revolute ones), a
configuration-dependent mass matrix and no constraints. Two formulations that share nothing
make an agreement between them worth having (docs/numerics.md, section "The independent
multibody reference").

- :mod:`.tree`: bodies, joints (free root, spherical, revolute), validation, world states to
  joint coordinates and back, and a tree built from bodies in their world state and joints
  between pairs of bodies (:func:`.tree.tree_from_world`, the form of a director system).
- :mod:`.dynamics`: composite-rigid-body algorithm, recursive Newton-Euler, invariants.
- :mod:`.integrate`: DOP853 at rtol 1e-13, error estimate, cost bound, per-body world output.
- :mod:`.exact`: a straight chain spinning about a perpendicular principal axis, a double
  conical pendulum in steady rotation, the parallelogram four-bar as a planar pendulum.
- :mod:`.horizon`: the horizon over which a trajectory reference of a chaotic system means
  something.
"""

from __future__ import annotations

from references.exact.multibody.dynamics import (
    body_states,
    invariants,
    mass_matrix_and_bias,
    rhs,
)
from references.exact.multibody.exact import (
    DoubleConicalPendulum,
    ParallelogramFourBar,
    SpinningChain,
    straight_chain,
)
from references.exact.multibody.horizon import Horizon, trajectory_horizon
from references.exact.multibody.integrate import (
    RTOL,
    MultibodySolution,
    ReferenceCostExceeded,
    solve,
    solve_from_states,
)
from references.exact.multibody.tree import Body, Joint, Tree, tree_from_world

__all__ = [
    "RTOL",
    "Body",
    "DoubleConicalPendulum",
    "Horizon",
    "Joint",
    "MultibodySolution",
    "ParallelogramFourBar",
    "ReferenceCostExceeded",
    "SpinningChain",
    "Tree",
    "body_states",
    "invariants",
    "mass_matrix_and_bias",
    "rhs",
    "solve",
    "solve_from_states",
    "straight_chain",
    "trajectory_horizon",
    "tree_from_world",
]
