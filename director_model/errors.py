"""Exceptions of director_model.

Every input error is raised before any stepping and names the argument, the value and the rule
broken, so that callers (e.g. the scenario loader, which prefixes the file and field) can pass
the message on unchanged. Step failures are raised after the compiled loop reports a status
code; their message names the time reached and an estimate of the step-size limit.
"""

from __future__ import annotations


class InvalidBodyError(ValueError):
    """Mass, principal moments of inertia or pivot do not describe a physical rigid body that
    the director model can integrate (non-positive or non-finite values, triangle inequality
    violated, thin rod)."""


class InvalidStateError(ValueError):
    """An initial state is malformed: wrong shape, non-finite entries, a rotation matrix that
    is not orthonormal to 1e-12 or has det = -1, or a centre-of-mass state given for a pivoted
    body that contradicts the pivot."""


class InvalidRunError(ValueError):
    """Run settings are malformed: unknown scheme, dt/t_end not positive and finite, t_end not
    a whole number of steps, save_every not a whole number >= 1."""


class StepSizeError(RuntimeError):
    """A step could not be solved (no admissible solution of the implicit equations, Newton
    not converging, or a non-finite state). Attributes: ``time`` (s, the time reached, i.e.
    the start of the failing step), ``step`` (index of the failing step, 1-based), ``dt``,
    ``h_max`` (s, estimate of the largest usable step at the failing state, or None) and
    ``body`` (index in a batch, or None)."""

    def __init__(self, message: str, *, time: float, step: int, dt: float, h_max, body=None):
        super().__init__(message)
        self.time = time
        self.step = step
        self.dt = dt
        self.h_max = h_max
        self.body = body
