"""Exceptions and warnings shared by every package of psdm-casadi.

Each subclasses a builtin so callers may catch either the specific class or the builtin.
Messages follow one template: *Owner.field must be constraint; got value. Fix.*
"""


class PSDMError(Exception):
    """Base class of every error raised on purpose by psdm-casadi."""


class ShapeError(PSDMError, ValueError):
    """An array has the wrong shape or length."""


class ParameterError(PSDMError, ValueError):
    """A value is outside its allowed range or of the wrong kind."""


class RobotFileError(ParameterError):
    """A robot description file (TOML or URDF) is malformed."""


class RecordingError(ParameterError):
    """A recording (CSV/NPZ) is malformed: columns, NaN, time, length."""


class InsufficientExcitationError(RecordingError):
    """A recording does not excite what is identified from it: a joint barely moves, or the regressor is singular.

    ``joints`` (0-based) names the joints that did not move enough or whose parameters are not excited,
    ``columns`` the regressor columns (parameter names) that are not excited.
    """

    def __init__(self, message, joints=(), columns=()):
        super().__init__(message)
        self.joints = tuple(int(j) for j in joints)
        self.columns = tuple(str(c) for c in columns)


class ModelFileError(ParameterError):
    """A saved model file is unreadable, of another format, or of another version."""


class NotFittedError(PSDMError, ValueError, AttributeError):
    """An estimator was used before ``fit``."""


class SolverError(PSDMError, RuntimeError):
    """A numerical solver (Ipopt, a factorisation) failed; the message carries its status.

    ``joint`` (0-based, None when the solve was not one joint's) lets a caller name the joint in its own words.
    """

    def __init__(self, message, status=None, iterations=None, joint=None):
        super().__init__(message)
        self.status = status
        self.iterations = iterations
        self.joint = joint


class DerivationError(PSDMError, RuntimeError):
    """The PSDM derivation could not reproduce the oracle to the required accuracy."""


class ExcitationWarning(UserWarning):
    """An excitation trajectory is poorly conditioned or close to a limit."""


class SelectionWarning(UserWarning):
    """A model selection is unstable or a term was kept on weak evidence."""
