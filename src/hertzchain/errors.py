"""Exceptions and warnings raised by hertzchain.

They are kept in one small module so that the CLI can turn every *user* error into a one
paragraph message with exit status 2, while genuine bugs still show a traceback.
"""

from __future__ import annotations


class HertzchainError(Exception):
    """Base class of the errors a user can cause (bad input, a diverging run...)."""


class ConfigError(HertzchainError, ValueError):
    """An input value is invalid.

    Parameters
    ----------
    field
        Dotted name of the offending field, e.g. ``"chain.diameters_mm[3]"``.
    message
        What was wrong and what is allowed.
    """

    def __init__(self, field: str, message: str):
        self.field = field
        self.message = message
        super().__init__(f"{field}: {message}")

    def __reduce__(self):
        # rebuilt from (field, message), not from the one formatted argument Exception pickles:
        # an error raised in a forked worker (a trace that cannot be written) reaches the parent
        return type(self), (self.field, self.message)


class SimulationDiverged(HertzchainError, FloatingPointError):
    """The integration produced non-finite numbers (time step far too large, bad input)."""


class PulseNotFound(HertzchainError, ValueError):
    """A signal holds no pulse that the analysis can fit."""


class ObjectiveUndefined(ConfigError, PulseNotFound):
    """A result asked for (a sensitivity's objective) is identically zero or undefined over the run
    (the pulse never reaches the wall, a window outside the run); ``field`` names what to change.
    A PulseNotFound too: a search that ranks such a candidate as infeasible catches both."""


class PulseClipped(PulseNotFound):
    """The pulse of a record is clipped (a saturated sensor or scope): its fit would be wrong."""


class TooManySteps(ConfigError):
    """A run would take an absurd number of time steps (:func:`hertzchain.checks.check_step_count`);
    ``field`` names the input that sets its step."""


class ElasticLimitWarning(UserWarning):
    """Contact forces passed the elastic limit (yield) estimated as in the paper, Sec. II."""


class DurationWarning(UserWarning):
    """An automatic run duration (``duration = "auto"``) may be too short for the wall pulse."""


class HertzRangeWarning(UserWarning):
    """A contact overlap passed the range of Hertz theory (a fraction of the smaller radius, paper eq. 1)."""


class PulseNotReachedWarning(UserWarning):
    """The record ended before the pulse reached the wall (the wall force is 0 for want of time)."""


class LongRunWarning(UserWarning):
    """A run is projected to take more than a few minutes (the estimate is in the message)."""


class CheckpointWarning(UserWarning):
    """A checkpoint could not be used (damaged, foreign, of an older format): it was set aside."""
