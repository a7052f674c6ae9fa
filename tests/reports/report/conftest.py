"""The small real suite the report's tests read: cone_top and free_tumbling for 0.5 s at
dt = 2e-3 on four engines, with failures in it, run and reported once per test process."""

import pytest

import scenarios
from reports.run.plan import plan
from reports.run.runner import run_suite
from reports.store.results import read_results

#: cone_top at dt = 1e-3 and 2e-3: semi-implicit Euler diverges (at t = 0.22 s at 1e-3 in the
#: default suite), RK4 and RKMK4 run one algorithm on two engines; 0.5 s keeps it short
ENGINES = ("director", "exact", "mujoco", "pinocchio")
INTEGRATORS = ("rattle", "rattle4", "energy_momentum", "reference", "Euler", "RK4", "RKMK4")


@pytest.fixture(scope="session")
def folder(tmp_path_factory):
    out = tmp_path_factory.mktemp("report")
    cone = scenarios.load("cone_top").replace(t_end=0.5, dt_sweep=(2e-3,))
    free = scenarios.load("free_tumbling").replace(t_end=0.5, dt_sweep=(2e-3,))
    specs = plan([cone, free], ENGINES, INTEGRATORS)
    run_suite(specs, out, progress=False)
    from reports.report.build import build_report

    build_report(out)
    return out


@pytest.fixture(scope="session")
def df(folder):
    return read_results(folder)
