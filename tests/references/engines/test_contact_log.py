"""ContactLog, the rows every contact builder logs: a row that is not finite or whose normal
is not a unit vector is refused naming the pair and the value (the law residuals are computed
from these rows; a NaN among them would pass through a max or a sum silently)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from references.engines.contact import NORMAL_UNIT_TOL, ContactLog


def test_a_unit_normal_row_is_kept_and_copied():
    log = ContactLog()
    normal = np.array([0.0, 0.0, 1.0])
    log.add(0, [0.1, 0.0, 0.0], normal, [0.0, 0.0, 9.81], 1e-4)
    normal[:] = 0.0  # the engine reuses its memory: the row keeps what was logged
    log.save()
    rows = log.arrays()
    assert rows["pair"].tolist() == [[0]]
    assert rows["normal"][0, 0].tolist() == [0.0, 0.0, 1.0]
    assert rows["depth"][0, 0] == 1e-4


@pytest.mark.parametrize(
    "normal, said",
    [
        ([0.0, 0.0, 0.0], "has length 0"),  # a mean of normals that cancel or of none
        ([math.nan, 0.0, 1.0], "normal [nan"),  # 0/0 of a normalised zero vector
        ([0.0, 0.0, 2.0], "has length 2"),  # a normal not normalised
        ([0.0, 0.0, 1.0 + 10 * NORMAL_UNIT_TOL], "rule: a unit vector"),
    ],
)
def test_a_bad_normal_is_refused_naming_pair_and_value(normal, said):
    log = ContactLog()
    with pytest.raises(ValueError, match="pair 3") as err:
        log.add(3, [0.0, 0.0, 0.0], normal, [0.0, 0.0, 1.0])
    assert said in str(err.value)
    assert log.current == []


@pytest.mark.parametrize("field", ["point", "force"])
def test_a_non_finite_point_or_force_is_refused(field):
    row = {"point": [0.0, 0.0, 0.0], "force": [0.0, 0.0, 1.0]}
    row[field] = [0.0, math.inf, 0.0]
    with pytest.raises(ValueError, match=f"pair 1: {field} "):
        ContactLog().add(1, row["point"], [0.0, 0.0, 1.0], row["force"])
