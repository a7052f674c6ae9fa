"""Polynomial roots in mpmath across its releases, for tests that build independent references.

mpmath 1.4 deprecates coefficients in descending order unless ``asc`` is given; 1.3 has no
``asc``. The tests write their polynomials with the highest power first, as in the formulas.
"""

import inspect

import mpmath as mp

_HAS_ASC = "asc" in inspect.signature(mp.polyroots).parameters


def polyroots(coeffs, **kwargs):
    """Roots of ``coeffs[0] x^n + ... + coeffs[n]`` (highest power first), as mpmath gives them."""
    if _HAS_ASC:
        return mp.polyroots(list(coeffs)[::-1], asc=True, **kwargs)
    return mp.polyroots(list(coeffs), **kwargs)
