"""References: the engines that produce trajectories (director_model, the exact solutions,
MuJoCo, Pinocchio, DART, PyBullet) behind one interface, and the one trajectory schema."""

from references.trajectory import COLUMNS, Trajectory

__all__ = ["COLUMNS", "Trajectory"]
