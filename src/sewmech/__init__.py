"""sewmech: kinematics, dynamics, balancing and optimisation of sewing-machine mechanisms.

Units everywhere inside: mm, kg, s, N, rad. Degrees appear only at the edges (files, CLI,
plots) and are named so (``phi_deg``).
"""

from .errors import AssemblyError, ConvergenceError, MachineFileError, SewmechError
from .kinematics import KinematicsPlan, kinematics, rpm_to_rad_s
from .machine import Machine, compile_machine, load_machine, machine_from_toml, shipped_machines
from .results import KinematicsResult, LinkMotion, PointMotion, VariableMotion
from .spec import MachineSpec, load_machine_spec, parse_machine

__version__ = "0.1.0"

__all__ = [
    "AssemblyError",
    "ConvergenceError",
    "KinematicsPlan",
    "KinematicsResult",
    "LinkMotion",
    "Machine",
    "MachineFileError",
    "MachineSpec",
    "PointMotion",
    "SewmechError",
    "VariableMotion",
    "compile_machine",
    "kinematics",
    "load_machine",
    "load_machine_spec",
    "machine_from_toml",
    "parse_machine",
    "rpm_to_rad_s",
    "shipped_machines",
]
