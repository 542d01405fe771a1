"""psdm_casadi: derive a minimal regressor dynamic model (PSDM) of a robot arm and evaluate it with CasADi."""

from psdm_casadi.derive import DeriveOptions, derive_psdm
from psdm_casadi.model import PSDMModel, load_model
from psdm_casadi.robot import DriveParameters, Joint, LinkInertia, RobotDescription, from_dh, from_urdf, load_robot

__all__ = [
    "DeriveOptions",
    "DriveParameters",
    "Joint",
    "LinkInertia",
    "PSDMModel",
    "RobotDescription",
    "derive_psdm",
    "from_dh",
    "from_urdf",
    "load_model",
    "load_robot",
]
