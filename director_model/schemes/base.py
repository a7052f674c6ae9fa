"""The interface of an integration scheme: data on a class, stepping in the compiled kernels.

A scheme declares its ``name`` (registry key), its ``order``, a one-line ``description``, and
a long class docstring saying what it conserves and where it comes from. The compiled time
loop (:mod:`director_model._kernels`) is shared; a scheme selects its step by ``method`` (a
kernel code) and, for the RATTLE family, by ``coefficients``: one step of the scheme is the
composition of RATTLE steps of sizes ``coefficients[k] * dt``.

``limit_factor`` turns the body angular velocity |W| (rad/s) at a failing state into the
step-size estimate h_max = limit_factor / |W| quoted in :class:`StepSizeError`.
"""

from __future__ import annotations

from typing import ClassVar

import numpy as np


class Scheme:
    name: ClassVar[str]
    order: ClassVar[int]
    description: ClassVar[str]
    method: ClassVar[int]
    coefficients: ClassVar[tuple[float, ...]] = (1.0,)
    limit_factor: ClassVar[float]
    #: a short text for error messages: what the limit estimate is based on
    limit_rule: ClassVar[str]

    @classmethod
    def coefficient_array(cls) -> np.ndarray:
        return np.array(cls.coefficients, dtype=float)

    @classmethod
    def h_max(cls, omega_norm: float) -> float:
        """Estimated largest step at body angular speed ``omega_norm`` (rad/s)."""
        return float("inf") if omega_norm == 0 else cls.limit_factor / omega_norm
