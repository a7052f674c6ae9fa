"""The interface of an integration scheme: data on a class, stepping in the compiled kernels.

A scheme declares its ``name`` (registry key), its ``order``, a one-line ``description``, and
a long class docstring saying what it conserves and where it comes from. The compiled time
loop (:mod:`director_model._kernels`) is shared; a scheme selects its step by ``method`` (a
kernel code) and, for the RATTLE family, by ``coefficients``: one step of the scheme is the
composition of RATTLE steps of sizes ``coefficients[k] * dt``.

``limit_factor`` turns the body angular velocity |W| (rad/s) at a failing state into the
step-size estimate h_max ~ limit_factor / |W| quoted in :class:`StepSizeError` (see
:meth:`Scheme.h_max`, which also accounts for the torque's half-kick).
"""

from __future__ import annotations

import math
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
    def h_max(cls, omega_norm: float, alpha_norm: float = 0.0) -> float:
        """Estimated largest step at body angular speed |W| = ``omega_norm`` (rad/s) and
        angular acceleration |Ibar^{-1} tau| = ``alpha_norm`` (rad/s^2).

        RATTLE's sub-step of size c h must satisfy c h |pi|/I < 1 for a principal-axis spin,
        with pi = Pi + c h/2 tau the half-kicked momentum, i.e. y |W| + y^2 alpha/2 < 1 for
        y = c h; its root y = 2/(|W| + sqrt(|W|^2 + 2 alpha)) (= 1/|W| without torque),
        divided by c (``limit_factor`` = 1/c, times 2 for energy-momentum).
        """
        w, a = float(omega_norm), float(alpha_norm)
        if w > 0.0:
            root = w * math.sqrt(1.0 + 2.0 * a / w / w)  # no overflow for huge |W|
        else:
            root = math.sqrt(2.0 * a)
        if w + root == 0.0:
            return float("inf")
        return cls.limit_factor * 2.0 / (w + root)
