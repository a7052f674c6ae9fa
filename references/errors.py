"""The failures of an engine run, each with the ``status`` the runner writes to the results."""

from __future__ import annotations


class EngineError(Exception):
    """A fault of the adapter or the suite (a model that does not hold the scenario, an
    initial state the engine does not reproduce); ``status`` is written to the results."""

    status = "error"


class EngineUnavailable(EngineError):
    """The engine's Python package is not installed or does not import."""

    status = "unavailable"


class Unsupported(EngineError):
    """The scenario (or integrator) cannot be represented by this engine."""

    status = "unsupported"


class Diverged(EngineError):
    """The run did not survive: a non-finite state, an energy error beyond 100 % of the
    scenario's energy scale, an engine limit reached (a velocity clamp), or a step the
    integrator could not take. ``t_diverged`` is when it was seen (s); ``output`` holds the
    run up to the last state checked before that (a
    :class:`~references.engines.context.RunOutput`), or None."""

    status = "diverged"

    def __init__(self, message: str, t_diverged: float, output=None):
        super().__init__(message)
        self.t_diverged = float(t_diverged)
        self.output = output


class StepFailure(ArithmeticError):
    """Raised by an adapter's ``advance`` or ``forward_dynamics`` when a step cannot be taken
    (an implicit step with no solution, a stage rotation beyond a half turn); the run loop
    turns it into :class:`Diverged` at the time of that step. The raiser says which step:
    ``time`` (s, the absolute time the failing step starts from) or ``steps_taken`` (the steps
    the failing call completed before it); with neither, only the block is known. ``states``
    (optional): the states of the checkpoints the call completed before the failure (a
    :class:`~references.conventions.BodyState` of stacked arrays). A stepper that catches the
    failure of a call it made may fill in what the raiser could not know (the RKMK4 steppers
    set ``steps_taken`` and ``states`` on a stage's failure)."""

    def __init__(
        self,
        message: str,
        *,
        time: float | None = None,
        steps_taken: int | None = None,
        states=None,
    ):
        super().__init__(message)
        self.time = time
        self.steps_taken = steps_taken
        self.states = states
