"""Compile a :class:`~sewmech.spec.MachineSpec` once into a :class:`Machine` of index arrays.

Names are resolved here, once: every point, link, joint variable and numeric parameter gets an
index, and each unit becomes one row of an integer program that the compiled interpreter in
:mod:`sewmech._kernels` walks. Every numeric value of the file is a named *parameter* (lengths in
mm, angles in rad), so a batch of designs is just an array of parameter vectors.
"""

from __future__ import annotations

import dataclasses
import difflib
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from functools import cached_property
from importlib import resources
from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from . import _kernels as K
from .cams import CONSTANT_WIDTH_KEYS, constant_width_arcs, constant_width_fault
from .counterweights import PARAMETERS as CW_PARAMETERS
from .counterweights import Counterweight
from .errors import MachineFileError, ParameterError, name_index
from .mass import from_spec as mass_from_spec
from .paths import user_path
from .physics_checks import check_conditions, check_friction, check_springs
from .spec import (
    FRAME,
    SHAFT,
    CrankUnit,
    LoopUnit,
    MachineSpec,
    PointUnit,
    RPRUnit,
    RRPUnit,
    RRRUnit,
    load_machine_spec,
    parse_machine,
    validate_model,
)

MACHINES_PACKAGE = "sewmech.data.machines"


@dataclass(frozen=True)
class Pair:
    """One kinematic pair of the force analysis; its unknowns are the action of ``links[0]``
    on ``links[1]``.

    kind:
      - ``"revolute"``: a pin at ``point``; unknowns Fx, Fy (N).
      - ``"prismatic"``: a slider on its guide; unknowns N (N) along the guide's normal (the
        line direction turned +90 deg) through ``point`` and a couple M (N mm).
      - ``"cam"``: a cam contact; unknown N (N) along the cam term's outward normal through the
        contact point (positive: the cam pushes the follower).
      - ``"slot"``: a pin in a slot or a roller on a flat; unknown N (N) along the slot line's
        normal through ``point``.
      - ``"driver"``: the torque (N mm) that turns a crank (``input`` "shaft": the motor; a
        setting input such as the stitch regulator: the torque that holds the setting).
    """

    name: str
    kind: str
    links: tuple[str, str]
    unit: str
    point: str | None = None
    line_link: str | None = None  # prismatic/slot: the line's direction link; cam: normal link
    line_var: str | None = None  # cam: the normal from an angle variable
    line_param: int = -1  # parameter index of an angle added to the direction (rad), -1: none
    extra_angle: float = 0.0  # a fixed angle added to the direction (rad)
    terms: tuple[int, ...] = ()  # cam: the loop's other terms (global term rows)
    cam_term: int = -1  # cam: the cam term's global row
    input: str | None = None  # driver: "shaft" or a setting input's name
    ratio_param: int = -1  # driver: parameter index of the crank's speed ratio
    one_sided: bool = False  # cam, slot: the contact can only push (N >= 0), else it opens


@dataclass(frozen=True, eq=False)
class Machine:
    """A compiled machine: immutable, built once, shared by every evaluation.

    Attributes
    ----------
    spec : MachineSpec
        The validated machine file.
    file : str
        Where it came from.
    point_names, link_names, variable_names : tuple[str, ...]
        Names in index order. Link 0 is always ``"frame"``.
    variable_units : tuple[str, ...]
        ``"mm"`` (slider displacements, lengths) or ``"rad"`` (free angles) per variable.
    parameter_names, parameter_units : tuple[str, ...]
        Every numeric value of the file, in internal units (mm, rad, or 1).
    defaults : ndarray, shape (n_parameters,)
        The parameter values of the file.
    unit_names, unit_types : tuple[str, ...]
        The units in solve order.
    branches : dict[str, int]
        The assembly branch (+1/-1) of every closed-form unit that has one.
    point_links : dict[str, tuple[str, ...]]
        The links each point belongs to (a joint belongs to two).
    cam_designs : dict[str, dict[str, float]]
        Design values (width, stroke mm; dwell, orientation rad) of every cam built from
        ``constant_width``; ``Machine.parameters`` accepts them as ``CAM.width`` etc.
    pairs : tuple[Pair, ...]
        The kinematic pairs of the force analysis (see :class:`Pair`), in unknown order.
    mass_origins : dict[str, str]
        The point at the origin of each ``[masses]`` link's frame.
    parameter_lo, parameter_hi : ndarray, shape (n_parameters,)
        The domain of each parameter, internal units: lengths of links, rods, loop terms and
        cam arcs at least :data:`MIN_LENGTH`, setting inputs within their declared range,
        every other parameter within +-:data:`PARAM_LIMIT`. A design outside it is not
        evaluated: it fails (``on_failure``) naming the parameter.
    parameter_owner : tuple[int, ...]
        Index into ``unit_names`` of the unit that defines each parameter (-1: frame points,
        setting inputs, cams not used by a loop unit).
    changes : dict[str, float]
        The parameters changed by :meth:`with_parameters` (``--set``), internal units.
    parameter_sources : tuple
        Where each parameter's value sits in the machine file (a path of keys), or None when
        it cannot be set on its own (the arcs of a ``constant_width`` cam: set its design
        values); :meth:`with_parameters` and :meth:`parameter_location` read it.
    counterweights : tuple[Counterweight, ...]
        The ``[counterweights]`` of the file (:mod:`sewmech.engine.counterweights`), each with
        its three parameters.
    """

    spec: MachineSpec
    file: str
    point_names: tuple[str, ...]
    link_names: tuple[str, ...]
    variable_names: tuple[str, ...]
    variable_units: tuple[str, ...]
    parameter_names: tuple[str, ...]
    parameter_units: tuple[str, ...]
    defaults: np.ndarray
    unit_names: tuple[str, ...]
    unit_types: tuple[str, ...]
    branches: dict[str, int]
    point_links: dict[str, tuple[str, ...]]
    program: np.ndarray = field(repr=False)
    groups: np.ndarray = field(repr=False)
    unknowns: np.ndarray = field(repr=False)
    terms: np.ndarray = field(repr=False)
    cams: np.ndarray = field(repr=False)
    arcs: np.ndarray = field(repr=False)
    kernel_unit_of_row: tuple[int, ...] = field(repr=False)
    cam_designs: dict[str, dict[str, float]] = field(default_factory=dict, repr=False)
    pairs: tuple[Pair, ...] = field(default=(), repr=False)
    mass_origins: dict[str, str] = field(default_factory=dict, repr=False)
    parameter_sources: tuple = field(default=(), repr=False)
    parameter_owner: tuple[int, ...] = field(default=(), repr=False)
    parameter_lo: np.ndarray = field(default=None, repr=False)
    parameter_hi: np.ndarray = field(default=None, repr=False)
    changes: dict[str, float] = field(default_factory=dict, repr=False)
    counterweights: tuple[Counterweight, ...] = field(default=(), repr=False)

    # ---- names -----------------------------------------------------------------------------
    @property
    def name(self) -> str:
        return self.spec.machine.name

    @property
    def has_loops(self) -> bool:
        return self.groups.shape[0] > 0

    @cached_property
    def period_turns(self) -> int | None:
        """Shaft turns after which every crank is back where it started (1 for a machine whose
        shaft-driven cranks all turn at whole-number ratios, 2 with a crank at ratio 0.5); None
        when the motion does not repeat within 100 turns."""
        return period_turns(u.ratio for u in self.spec.units
                            if u.type == "crank" and u.input == SHAFT)

    @cached_property
    def angle_readers(self) -> np.ndarray:
        """Mask over links whose angle (not only its cos/sin) a later unit reads."""
        need = np.zeros(len(self.link_names), dtype=np.bool_)
        rrp = self.program[self.program[:, 0] == K.OP_RRP]
        need[rrp[:, 3]] = True  # the guide link of a slider
        t = self.terms
        vec = t[(t[:, 0] != K.TERM_POINT) & (t[:, 5] == K.SRC_LINK)]
        need[vec[:, 6]] = True  # angles in loop terms
        need[self.cams[:, 0]] = True  # cam links
        need[0] = True  # the frame: theta = 0 always
        need.setflags(write=False)
        return need

    @property
    def rpm(self) -> float:
        """Working speed of the upper shaft from the file, rev/min."""
        return float(self.spec.speed.rpm)

    @property
    def reference_phi(self) -> float:
        """Shaft angle (rad) at the convention's reference event."""
        return math.radians(self.spec.convention.reference_phi_deg)

    @property
    def assembly_phi(self) -> float:
        """Shaft angle (rad) where loop units start from their initial guesses."""
        c = self.spec.convention
        return math.radians(c.assembly_phi_deg if c.assembly_phi_deg is not None
                            else c.reference_phi_deg)

    def _index(self, names: tuple[str, ...], name: str, what: str) -> int:
        return name_index(names, name, what, f"machine '{self.name}'")

    def point_index(self, name: str) -> int:
        return self._index(self.point_names, name, "point")

    def link_index(self, name: str) -> int:
        return self._index(self.link_names, name, "link")

    def variable_index(self, name: str) -> int:
        return self._index(self.variable_names, name, "joint variable")

    def parameter_index(self, name: str) -> int:
        return self._index(self.parameter_names, name, "parameter")

    @cached_property
    def _row_io(self) -> list[tuple[set, set]]:
        """(reads, writes) of every kernel row, as ("p" | "l" | "v", index) pairs."""
        out = []
        t, unk = self.terms, self.unknowns
        for row in self.program:
            op = int(row[0])
            r: set = set()
            w: set = set()
            if op == K.OP_FIXED:
                w = {("p", row[1])}
            elif op == K.OP_CRANK:
                w = {("l", row[1])}
            elif op == K.OP_POINT:
                r, w = {("l", row[2]), ("p", row[3])}, {("p", row[1])}
            elif op == K.OP_RRR:
                r, w = {("p", row[1]), ("p", row[2])}, {("p", row[3]), ("l", row[4]),
                                                         ("l", row[5])}
            elif op == K.OP_RRP:
                r = {("p", row[1]), ("p", row[2]), ("l", row[3])}
                w = {("p", row[4]), ("l", row[5]), ("l", row[6]), ("v", row[11])}
            elif op == K.OP_RPR:
                r, w = {("p", row[1]), ("p", row[2])}, {("l", row[3]), ("v", row[7])}
                if row[4] >= 0:
                    w.add(("l", row[4]))
            else:  # a loop group: its unknowns, from its terms' known quantities
                n, u0, _, t0, nt = (int(x) for x in self.groups[row[1]])
                w = {("l" if unk[j, 0] == 0 else "v", unk[j, 1]) for j in range(u0, u0 + n)}
                for term in t[t0:t0 + nt]:
                    if term[0] == K.TERM_POINT:
                        r.add(("p", term[4]))
                        continue
                    if term[0] == K.TERM_VEC and term[3] == K.SRC_VAR and term[10] < 0:
                        r.add(("v", term[4]))
                    if term[11] < 0:
                        r.add(("l" if term[5] == K.SRC_LINK else "v", term[6]))
                    if term[0] == K.TERM_CAM:
                        cam = self.cams[term[8]]
                        r |= {("l", cam[0]), ("p", cam[1])}
            out.append(({(k, int(i)) for k, i in r}, {(k, int(i)) for k, i in w}))
        return out

    def rows_for(self, pt_sel, lk_sel, var_sel) -> np.ndarray:
        """Kernel rows (in solve order) that the given outputs depend on: only these run."""
        need = ({("p", int(i)) for i in pt_sel} | {("l", int(i)) for i in lk_sel}
                | {("v", int(i)) for i in var_sel})
        keep = []
        for k in range(len(self._row_io) - 1, -1, -1):
            reads, writes = self._row_io[k]
            if writes & need:
                keep.append(k)
                need |= reads
        rows = np.asarray(keep[::-1], dtype=np.int64)
        rows.setflags(write=False)
        return rows

    def with_parameters(self, values: Mapping[str, float], *,
                        origin: str = "with_parameters") -> Machine:
        """A new machine with some file values changed (see :func:`with_parameters`)."""
        return with_parameters(self, values, origin=origin)

    def parameter_location(self, name: str) -> tuple[str, str] | None:
        """(table, key) of a parameter's value in the machine file; None for the arcs of a
        constant-width cam (their design values are in ``cams.NAME.constant_width``)."""
        src = self.parameter_sources[self.parameter_index(name)]
        return None if src is None else parameter_location(self.spec, src)

    def upstream_units(self, unit: int) -> list[int]:
        """Indices of the units whose outputs unit ``unit`` reads, directly or through other
        units, in solve order."""
        rows = [k for k, u in enumerate(self.kernel_unit_of_row) if u == unit]
        if not rows:
            return []
        need = set().union(*(self._row_io[k][0] for k in rows))
        found = set()
        for k in range(min(rows) - 1, -1, -1):
            reads, writes = self._row_io[k]
            if writes & need:
                need |= reads
                if self.kernel_unit_of_row[k] >= 0:
                    found.add(self.kernel_unit_of_row[k])
        return sorted(found - {unit})

    def selection(self, points=None, links=None, variables=None):
        """Names and indices of the returned points, links and joint variables (None: all).

        Returns ``(pt_names, pt_sel, lk_names, lk_sel, var_names, var_sel, need_th, rows)``
        where ``need_th`` marks the links whose angle the kernel must compute and ``rows`` the
        kernel rows the outputs depend on (the only ones evaluated). Cached per selection:
        optimisation loops call kinematics thousands of times with the same selection.
        """
        key = tuple(None if w is None else (w,) if isinstance(w, str) else tuple(w)
                    for w in (points, links, variables))
        hit = self._selections.get(key)
        if hit is not None:
            return hit
        out = []
        for names, wanted, index in ((self.point_names, key[0], self.point_index),
                                     (self.link_names, key[1], self.link_index),
                                     (self.variable_names, key[2], self.variable_index)):
            idx = (np.arange(len(names), dtype=np.int64) if wanted is None else
                   np.asarray([index(n) for n in wanted], dtype=np.int64).reshape(-1))
            idx.setflags(write=False)
            out += [tuple(names[i] for i in idx), idx]
        need = self.angle_readers.copy()
        need[out[3]] = True
        need.setflags(write=False)
        out.append(need)
        out.append(self.rows_for(out[1], out[3], out[5]))
        self._selections[key] = hit = tuple(out)
        return hit

    def check_loads(self, loads, file: str = "<loads>") -> None:
        """Check loads (e.g. from a load file) against this machine's links and points."""
        check_loads(self.name, self.link_names, self.point_names, self.point_links, loads, file)
        check_conditions(self.name, file, loads, self.point_names, self.link_names,
                         self.variable_names, self.spec.thread is not None)

    @cached_property
    def _selections(self) -> dict:
        return {}

    @cached_property
    def _plans(self) -> dict:
        """The prepared plans of recent one-off kinematics() calls."""
        return {}

    @cached_property
    def _tangent_plans(self) -> dict:
        """The tangent layouts of sensitivities() calls, per output selection
        (:mod:`sewmech.engine.sensitivity`)."""
        return {}

    @cached_property
    def _condition_maxima(self) -> dict:
        """The largest values over the turn of the channels that loads' conditions read
        (``within_of_max``), per design (:mod:`sewmech.engine.loads`)."""
        return {}

    @cached_property
    def _evaluations(self) -> dict:
        """The shared evaluations of designs (:func:`sewmech.engine.evaluation.evaluation`)."""
        return {}

    @cached_property
    def masses(self) -> dict:
        """Mass properties (:class:`sewmech.mass.MassProperties`) of every link that has a
        ``[masses.LINK]`` table, in the link's frame (mm, kg, kg mm^2)."""
        return {name: mass_from_spec(m) for name, m in self.spec.masses.items()}

    @cached_property
    def unit_of_row(self) -> np.ndarray:
        """Unit index (into unit_names) of each kernel row; -1 for fixed points; last = -1."""
        a = np.asarray(self.kernel_unit_of_row + (-1,), dtype=np.int64)
        a.setflags(write=False)
        return a

    # ---- designs -----------------------------------------------------------------------------
    def parameters(
        self,
        overrides: Mapping[str, ArrayLike] | None = None,
        *,
        inputs: Mapping[str, ArrayLike] | None = None,
        base: ArrayLike | None = None,
    ) -> np.ndarray:
        """Parameter vectors for a batch of designs.

        Parameters
        ----------
        overrides : mapping of parameter name -> array_like
            Values in internal units (mm, rad). All arrays broadcast to one batch shape. The
            design values of a constant-width cam (``CAM.width``, ``CAM.stroke`` in mm,
            ``CAM.dwell``, ``CAM.orientation`` in rad) rebuild its six arcs.
        inputs : mapping of input name -> array_like
            Setting inputs (e.g. the stitch regulator), rad; shorthand for ``input.NAME``.
        base : array_like, shape (n_parameters,) or batch + (n_parameters,), optional
            The values the overrides change (default: the file's); broadcast with them.

        Returns
        -------
        ndarray, shape batch_shape + (n_parameters,)
        """
        items: dict[int, np.ndarray] = {}
        designs: dict[str, dict[str, np.ndarray]] = {}
        for name, value in (overrides or {}).items():
            value = _finite_values(name, value)
            cam, _, key = name.rpartition(".")
            if cam in self.cam_designs and key in CONSTANT_WIDTH_KEYS:
                designs.setdefault(cam, {})[key] = value
                continue
            items[self.parameter_index(name)] = value
        for cam, given in designs.items():  # a cam design value moves all six arcs
            values = {**self.cam_designs[cam], **given}
            batch = any(np.ndim(v) for v in given.values())
            fault = None if batch else constant_width_fault(
                values["width"], values["stroke"], values["dwell"])
            if fault is not None:
                key = next(iter(given))
                raise ParameterError(f"{cam}.{key}", (), float(given[key]), fault,
                                     f"Choose {cam}'s width, stroke and dwell so that the cam"
                                     " is convex (`sewmech check --parameters` shows them)")
            # a batch: the designs that give no convex cam get NaN arcs, which the kinematics
            # reports as infeasible designs naming the arc
            arcs = constant_width_arcs(**values, nan_invalid=batch)
            for key, values in arcs.items():
                for k in range(6):
                    items[self.parameter_index(f"{cam}.arc{k}.{key}")] = values[..., k]
        for name, value in (inputs or {}).items():
            items[self.parameter_index(f"input.{name}")] = _finite_values(f"input.{name}", value)
        b = self.defaults if base is None else np.asarray(base, dtype=float)
        if b.shape[-1:] != self.defaults.shape:
            raise ValueError(f"base must end in ({self.defaults.size},) parameters, got {b.shape}")
        shape = np.broadcast_shapes(b.shape[:-1], *(v.shape for v in items.values()))
        out = np.empty(shape + (len(self.defaults),))
        out[...] = b
        for i, v in items.items():
            out[..., i] = v
        return out


#: internal unit -> (the unit machine files and the command line show it in, factor): angles
#: in degrees, counterweight masses in g and static moments in g cm; mm and 1 are shown as is
FILE_UNITS = {"rad": ("deg", 180.0 / math.pi), "kg": ("g", 1e3), "kg mm": ("g cm", 1e2)}


def file_value(value: float, unit: str) -> tuple[float, str]:
    """A parameter value (internal ``unit``) in the unit files and people use."""
    shown, factor = FILE_UNITS.get(unit, (unit, 1.0))
    return value * factor, shown


#: the largest magnitude of any parameter, internal units (mm, rad, 1): 1 km, and far from
#: overflow in the squares and products of the kernels
PARAM_LIMIT = 1e6
#: the shortest length of a link, rod, loop term or cam arc, mm (one nanometre)
MIN_LENGTH = 1e-6


_CAM_DESIGN_KEYS = {"width": ("width", 1.0), "stroke": ("stroke", 1.0),
                    "dwell": ("dwell_deg", 180.0 / math.pi),
                    "orientation": ("orientation_deg", 180.0 / math.pi)}


def with_parameters(machine: Machine, values: Mapping[str, float], *,
                    origin: str = "with_parameters") -> Machine:
    """A new machine whose file values are changed: ``values`` maps parameter names (as
    :meth:`Machine.parameters` takes them, cam design values included) to one value each,
    internal units (mm, rad).

    The change is made in the machine file's data and the result validated and compiled again,
    so every check of a machine file applies to it, and everything that reads the file (the
    report's tables, the timing, the feed) sees the new values. ``origin`` names where the
    values came from in error messages (e.g. ``--set``).

    Raises
    ------
    ParameterError
        An unknown name, a non-finite value, or a parameter that cannot be set on its own (an
        arc of a constant-width cam: set the cam's design values).
    MachineFileError
        The changed file is not a valid machine (e.g. a negative length).
    """
    raw = machine.spec.model_dump()
    for name, value in values.items():
        v = float(_finite_values(name, value))
        cam, _, key = name.rpartition(".")
        if cam in machine.cam_designs and key in _CAM_DESIGN_KEYS:
            file_key, scale = _CAM_DESIGN_KEYS[key]
            path, x = ("cams", cam, "constant_width", file_key), v * scale
        else:
            try:
                i = machine.parameter_index(name)
            except KeyError as exc:
                raise ParameterError(name, (), v, exc.args[0], "`sewmech check MACHINE"
                                     " --parameters` lists them all") from None
            path = machine.parameter_sources[i]
            if path is None:
                raise ParameterError(name, (), v, "is an arc of a constant-width cam and cannot"
                                     " be set on its own", f"Set {cam.split('.')[0]}.width,"
                                     " .stroke, .dwell or .orientation instead")
            x = v * FILE_UNITS.get(machine.parameter_units[i], ("", 1.0))[1]
        node = raw
        for part in path[:-1]:
            node = node[part]
        if isinstance(node, tuple):  # a (u, v) pair or a lengths pair: rebuild it as a list
            parent = raw
            for part in path[:-2]:
                parent = parent[part]
            node = parent[path[-2]] = list(node)
        node[path[-1]] = x
    where = f"{machine.file} ({origin} {', '.join(values)})"
    changed = compile_machine(validate_model(MachineSpec, raw, where), where)
    return dataclasses.replace(changed, file=machine.file,
                               changes={**machine.changes, **{k: float(v) for k, v in
                                                              values.items()}})


def _finite_values(name: str, value: ArrayLike) -> np.ndarray:
    """``value`` as a float array, or a :class:`ParameterError` naming the first design whose
    value is not a finite number."""
    try:
        a = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise ParameterError(name, (), math.nan, f"must be numbers (internal units, mm or rad),"
                             f" got {value!r}") from None
    bad = ~np.isfinite(a)
    if bad.any():
        k = tuple(int(i) for i in np.unravel_index(int(np.argmax(bad)), a.shape))
        raise ParameterError(name, k, float(a[k]), f"is {float(a[k])}: every value must be a"
                             " finite number", "nan and inf are not designs")
    return a


def _input_bounds(inp) -> tuple[float, float]:
    """Domain (rad) of a setting input: its declared range, else +-PARAM_LIMIT."""
    lo = math.radians(inp.min_deg) if inp.min_deg is not None else -PARAM_LIMIT
    hi = math.radians(inp.max_deg) if inp.max_deg is not None else PARAM_LIMIT
    return lo, hi


def domain_message(name: str, value: float, unit: str, lo: float, hi: float, *,
                   file_units: bool = False) -> tuple[str, str]:
    """(why ``value`` is outside [lo, hi], what to do), in the units the user sees (degrees
    in files and for setting inputs)."""
    deg = unit == "rad" and (file_units or name.startswith("input."))

    def show(x):
        if deg:
            return f"{math.degrees(x):.6g} deg"
        if unit in ("kg", "kg mm"):  # counterweights: always g and g cm
            return "{:.6g} {}".format(*file_value(x, unit))
        return f"{x:.6g} {unit}" if unit != "1" else f"{x:.6g}"

    cam, _, rest = name.partition(".arc")
    if math.isnan(value) and rest:  # a constant-width cam's arcs, rebuilt from design values
        return (f"is nan: {cam}'s design values (width, stroke, dwell) give no convex"
                " constant-width cam for this design",
                "Keep the stroke below the width and the dwell small enough for them")
    if not math.isfinite(value):
        return (f"is {value}: every number must be finite",
                "nan and inf are not values sewmech can compute with; give the number")
    if name.startswith("input.") and (lo > -PARAM_LIMIT or hi < PARAM_LIMIT):
        return (f"is {show(value)}: outside the range {show(lo)} .. {show(hi)} declared in"
                f" [inputs.{name[6:]}]", "Give a setting inside it, or widen min_deg/max_deg"
                " in the machine file")
    if lo == 0.0 and value < 0.0:
        return (f"is {show(value)}: a counterweight's mass or static moment cannot be negative",
                "Give 0 (no counterweight) or more; turn it by its angle or position instead")
    if lo == MIN_LENGTH:
        return (f"is {show(value)}: a length must be positive (at least {MIN_LENGTH:g} mm) and"
                f" at most {PARAM_LIMIT:g} mm", "Give a length inside that range")
    return (f"is {show(value)}: its magnitude must be at most {show(PARAM_LIMIT)}",
            "Give a value inside that range")


def parameter_location(spec: MachineSpec, path: tuple) -> tuple[str, str]:
    """(table, key) of a parameter's value in the machine file, as errors name them."""
    head = path[0]
    if head == "units":
        ui = path[1]
        table = f'units[{ui}] "{spec.units[ui].name}"'
        rest = path[2:]
    elif head in ("points", "inputs", "cams", "counterweights"):
        table = f"{head}.{path[1]}"
        rest = path[2:]
    else:
        table, rest = "", path
    key = ""
    for part in rest:
        key += f"[{part}]" if isinstance(part, int) else (f".{part}" if key else str(part))
    return table, key


def period_turns(ratios) -> int | None:
    """The least number of shaft turns after which cranks at these speed ratios are all back
    where they started; None if that is more than 100 turns."""
    from fractions import Fraction

    turns = 1
    for r in ratios:
        f = Fraction(r).limit_denominator(100)
        if abs(float(f) - r) > 1e-12:
            return None
        turns = math.lcm(turns, f.denominator)
        if turns > 100:
            return None
    return turns


#: how far from its link's origin a centre of mass may lie, in units of the machine's size
#: (its largest length or coordinate in mm): a link's material is within the machine
COM_REACH = 100.0


def check_loads(machine_name: str, links, points, point_links, loads, file: str) -> None:
    """Raise :class:`MachineFileError` (file, load, key) if a load names a link or point the
    machine lacks, the frame, a point that is not on its link, or its own point among the
    points it is pulled toward (no direction)."""
    moving = [lk for lk in links if lk != FRAME]
    for k, load in enumerate(loads):
        table = f'loads[{k}] "{load.name}"'
        if load.link == FRAME:
            raise MachineFileError(file, table, "link", "a load on the frame moves nothing (the"
                                   " frame takes every force through its pairs)",
                                   f"Name the moving link it acts on: {', '.join(moving)}")
        for key, value, names in (("link", load.link, moving), ("point", load.point, points)):
            if value not in names:
                close = difflib.get_close_matches(value, list(names), n=3)
                hint = (f"Did you mean {', '.join(close)}?" if close else
                        f"The machine's {key}s: {', '.join(names[:20])}"
                        + (f" and {len(names) - 20} more" if len(names) > 20 else ""))
                raise MachineFileError(file, table, key, f"machine '{machine_name}' has no"
                                       f" moving {key} '{value}'", hint)
        if load.link not in point_links[load.point]:
            on = [p for p in points if load.link in point_links.get(p, ())]
            raise MachineFileError(file, table, "point", f"'{load.point}' is not a point of link"
                                   f" '{load.link}' (it is on: {', '.join(point_links[load.point])})"
                                   f"; the points of '{load.link}' are: {', '.join(on)}",
                                   "Name one of them, or the link the point is on")
        for q in load.toward or ():
            if q not in points:
                raise MachineFileError(file, table, "toward", f"machine '{machine_name}' has no"
                                       f" point '{q}'")
            if q == load.point:
                raise MachineFileError(file, table, "toward", f"a load's toward points must"
                                       f" differ from its point ('{q}' is the load's own point:"
                                       " the direction from a point to itself is not defined)",
                                       "Name the points its line of action is pulled towards,"
                                       " or give angle_deg for a fixed direction")


# ---- compiler ---------------------------------------------------------------------------------


class _Names(list):
    """A list of names with a dict beside it: ``in`` and ``index`` in constant time, so that
    compiling a file of many points takes time linear in its size."""

    def __init__(self, names=()):
        super().__init__(names)
        self._pos = {n: i for i, n in enumerate(self)}

    def append(self, name):
        self._pos[name] = len(self)
        super().append(name)

    def index(self, name, *args):
        try:
            return self._pos[name]
        except KeyError:
            raise ValueError(f"{name!r} is not in the list") from None

    def __contains__(self, name):
        return name in self._pos


class _Compiler:
    def __init__(self, spec: MachineSpec, file: str):
        self.spec = spec
        self.file = file
        self.points: list[str] = _Names()
        self.point_links: dict[str, list[str]] = {}
        self.links: list[str] = _Names([FRAME])
        self.vars: list[str] = _Names()
        self.var_units: list[str] = []
        self.pnames: list[str] = _Names()
        self.punits: list[str] = []
        self.pvalues: list[float] = []
        self.psrc: list[tuple | None] = []  # path of each parameter's value in the file
        self.powner: list[int] = []  # unit index that defines it (-1: frame points, inputs)
        self.plo: list[float] = []  # domain of each parameter, internal units
        self.phi: list[float] = []
        self.cur_unit = -1
        self.rows: list[list[int]] = []
        self.row_unit: list[int] = []
        self.branches: dict[str, int] = {}
        self.groups: list[list[int]] = []
        self.unk: list[list[int]] = []
        self.terms: list[list[int]] = []
        self.cams: list[list[int]] = []
        self.arcs: list[list[int]] = []
        self.cam_index: dict[str, int] = {}
        self.cam_designs: dict[str, dict[str, float]] = {}
        self.pairs: list[Pair] = []
        self.contacts: list[tuple[str, str, object, dict]] = []  # (table, unit, contact, cams)
        # every name any unit will define, to tell "unknown" from "not solved yet"
        self.all_points, self.all_links = self._scan()

    # -- helpers
    def err(self, table: str, key: str, msg: str, hint: str = "") -> MachineFileError:
        return MachineFileError(self.file, table, key, msg, hint)

    def _com_within_reach(self, lname: str, mspec, props) -> None:
        """A link's centre of mass lies in its material, within the machine: one further out
        than :data:`COM_REACH` times the machine's size (its largest length or coordinate) is
        a slip of the value or its unit (``com = [1e8, 0]``: the force equations lost every
        digit to it and were reported singular "at a dead centre")."""
        size = max([abs(v) for v, u in zip(self.pvalues, self.punits, strict=True) if u == "mm"]
                   + [1.0])
        far = float(np.hypot(props.com[0], props.com[1]))
        if far > COM_REACH * size:
            raise self.err(f"masses.{lname}", "com" if mspec.solids is None else "solids",
                           f"puts the centre of mass {far:.3g} mm from the link's origin,"
                           f" {far / size:.3g} times the machine's size (its largest length or"
                           f" coordinate, {size:g} mm): no part of a link reaches so far, and"
                           " its force equations would lose every digit to it",
                           "Check the value and its unit (mm, in the link's frame)")

    def _not_moving(self, name: str, todo: str) -> tuple[str, str]:
        """(message, hint) for a name that should be a moving link and is not: the frame, or
        a name no unit moves; the hint names the close ones, or lists the moving links."""
        moving = list(self.links[1:])
        shown = ", ".join(moving[:20]) + (f" and {len(moving) - 20} more"
                                          if len(moving) > 20 else "")
        if name == FRAME:
            return (f"'{FRAME}' is not a moving link: masses and counterweights on it enter no"
                    " inertia force", f"{todo}: {shown}")
        close = difflib.get_close_matches(name, moving, n=3)
        return (f"'{name}' is not a moving link of this machine",
                f"Did you mean {', '.join(close)}?" if close
                else f"{todo}: {shown}")

    def param(self, name: str, value: float, unit: str, src: tuple | None = None, *,
              positive: bool = False, bounds: tuple[float, float] | None = None) -> int:
        """A new parameter: its value in internal units, the path of its value in the machine
        file (None: not settable on its own, e.g. the arcs of a constant-width cam) and its
        domain (a positive length, declared bounds, or any number within PARAM_LIMIT)."""
        self.pnames.append(name)
        self.punits.append(unit)
        self.pvalues.append(float(value))
        self.psrc.append(src)
        self.powner.append(self.cur_unit)
        lo, hi = bounds if bounds is not None else (MIN_LENGTH if positive else -PARAM_LIMIT,
                                                    PARAM_LIMIT)
        self.plo.append(lo)
        self.phi.append(hi)
        return len(self.pnames) - 1

    def _scan(self):
        pts = set(self.spec.points)
        links = {FRAME}
        for u in self.spec.units:
            if isinstance(u, CrankUnit):
                links.add(u.link or u.name)
                pts.update(u.points)
            elif isinstance(u, PointUnit):
                pts.update(u.points)
            elif isinstance(u, RRRUnit):
                pts.add(u.new)
                links.update(u.links)
            elif isinstance(u, RRPUnit):
                pts.add(u.new)
                links.update((u.rod, u.slider))
            elif isinstance(u, RPRUnit):
                links.add(u.link)
                if u.block:
                    links.add(u.block)
            elif isinstance(u, LoopUnit):
                links.update(u.unknown_links_deg)
        return pts, links

    def known_point(self, table: str, key: str, name: str) -> int:
        if name in self.points:
            return self.points.index(name)
        if name in self.all_points:
            raise self.err(table, key, f"point '{name}' is used before it is solved; move the unit"
                           " that solves it above this one (units are solved in file order)")
        close = difflib.get_close_matches(name, sorted(self.all_points), n=3)
        hint = f" Did you mean {', '.join(close)}?" if close else ""
        raise self.err(table, key, f"unknown point '{name}': it is neither a frame point"
                       f" ([points]) nor solved by any unit.{hint}")

    def known_link(self, table: str, key: str, name: str) -> int:
        if name in self.links:
            return self.links.index(name)
        if name in self.all_links:
            raise self.err(table, key, f"link '{name}' is used before the unit that moves it;"
                           " move that unit above this one")
        close = difflib.get_close_matches(name, sorted(self.all_links), n=3)
        hint = f" Did you mean {', '.join(close)}?" if close else ""
        raise self.err(table, key, f"unknown link '{name}'.{hint}")

    def new_point(self, table: str, key: str, name: str, links: tuple[str, ...]) -> int:
        if name in self.points:
            raise self.err(table, key, f"point '{name}' is already defined; every point is"
                           " solved once (pick another name)")
        self.points.append(name)
        self.point_links[name] = list(links)
        return len(self.points) - 1

    def new_link(self, table: str, key: str, name: str) -> int:
        if name in self.links:
            raise self.err(table, key, f"link '{name}' is already moved by an earlier unit;"
                           " every link is solved by exactly one unit")
        self.links.append(name)
        return len(self.links) - 1

    def new_var(self, table: str, key: str, name: str, unit: str) -> int:
        if name in self.vars:
            raise self.err(table, key, f"joint variable '{name}' is already defined")
        self.vars.append(name)
        self.var_units.append(unit)
        return len(self.vars) - 1

    def on_link(self, point: str, link: str):
        links = self.point_links.setdefault(point, [])
        if link not in links:
            links.append(link)

    def add_row(self, uidx: int, row: list[int]):
        self.rows.append(row + [0] * (K.UNIT_COLS - len(row)))
        self.row_unit.append(uidx)

    # -- passes
    def compile(self) -> Machine:
        spec = self.spec
        for name, p in spec.points.items():
            i = self.new_point(f"points.{name}", "", name, (FRAME,))
            self.add_row(-1, [K.OP_FIXED, i,
                              self.param(f"{name}.x", p.x, "mm", ("points", name, "x")),
                              self.param(f"{name}.y", p.y, "mm", ("points", name, "y"))])
        self.inputs = {}
        for name, inp in spec.inputs.items():
            self.inputs[name] = self.param(f"input.{name}", math.radians(inp.default_deg), "rad",
                                           ("inputs", name, "default_deg"),
                                           bounds=_input_bounds(inp))
        for ui, u in enumerate(spec.units):
            table = f'units[{ui}] "{u.name}"'
            self.cur_unit = ui
            getattr(self, f"unit_{u.type}")(ui, table, u)
        self.cur_unit = -1
        if self.groups:  # the loop solver continues over one turn and wraps
            for ui, u in enumerate(spec.units):
                if u.type == "crank" and u.input == SHAFT and u.ratio != round(u.ratio):
                    raise self.err(f'units[{ui}] "{u.name}"', "ratio", f"ratio = {u.ratio:g}:"
                                   " a machine with loop units must repeat every turn of the"
                                   " shaft (their solutions are continued over one turn)",
                                   "Give a whole-number ratio")
        for name, cam in spec.cams.items():
            if name not in self.cam_index:
                self.compile_cam(f"cams.{name}", name, cam)  # unused cams are still checked
        conv = spec.convention
        if conv.reference_point is not None:
            self.known_point("convention", "reference_point", conv.reference_point)
        if conv.reference_link is not None:
            self.known_link("convention", "reference_link", conv.reference_link)
        if spec.sewing is not None:  # roles must name parts that exist
            sew = spec.sewing
            for key in ("needle_point", "needle_eye", "take_up_eye", "shuttle_point"):
                if getattr(sew, key) is not None:
                    self.known_point("sewing", key, getattr(sew, key))
            if sew.shuttle_link is not None:
                self.known_link("sewing", "shuttle_link", sew.shuttle_link)
            for key in ("hook_crank", "feed_cam"):
                name = getattr(sew, key)
                if name is not None and not any(u.name == name and u.type == "crank"
                                                for u in spec.units):
                    raise self.err("sewing", key, f"'{name}' is not the name of a crank unit;"
                                   " name the upper-shaft crank that drives it")
            if sew.feed_dog is not None:
                self.known_point("sewing", "feed_dog", sew.feed_dog)
            if sew.regulator is not None and sew.regulator not in self.inputs:
                raise self.err("sewing", "regulator", f"unknown input '{sew.regulator}'; name one"
                               f" of [inputs] ({', '.join(self.inputs) or 'none defined'})")
            designs = {f"{c}.{k}" for c in self.cam_designs for k in CONSTANT_WIDTH_KEYS}
            for label, names in sew.feed_parameters.items():
                for pname in names:
                    if pname not in self.pnames and pname not in designs:
                        close = difflib.get_close_matches(pname, self.pnames, n=3)
                        hint = f" Did you mean {', '.join(close)}?" if close else ""
                        raise self.err("sewing", f"feed_parameters.{label}",
                                       f"unknown parameter '{pname}'.{hint}")
        for lname, mspec in spec.masses.items():
            if lname not in self.links or lname == FRAME:
                raise self.err(f"masses.{lname}", "", *self._not_moving(
                    lname, "Name the table [masses.LINK] after a moving link"))
            try:
                props = mass_from_spec(mspec)
            except ValueError as exc:
                key = "solids" if mspec.solids is not None else (
                    "inertia" if mspec.inertia is not None else "inertia_zz")
                raise self.err(f"masses.{lname}", key, str(exc)) from None
            self._com_within_reach(lname, mspec, props)
        if spec.thread is not None:
            for k, g in enumerate(spec.thread.guides):
                self.known_point("thread", f"guides[{k}].point", g.point)
            adj = spec.thread.adjust
            if adj is not None and adj.parameter not in self.pnames:
                close = difflib.get_close_matches(adj.parameter, self.pnames, n=3)
                hint = f" Did you mean {', '.join(close)}?" if close else ""
                raise self.err("thread.adjust", "parameter",
                               f"unknown parameter '{adj.parameter}'.{hint}")
        self.dynamics_checks()
        counterweights = self.compile_counterweights()
        names = [u.name for u in spec.units]
        dup = {n for n in names if names.count(n) > 1}
        if dup:
            n = sorted(dup)[0]
            raise self.err(f'units[{names.index(n)}] "{n}"', "name",
                           f"unit name '{n}' is used twice; unit names must be unique")

        def arr(rows, cols):
            a = np.asarray(rows, dtype=np.int64).reshape(-1, cols)
            a.setflags(write=False)
            return a

        for i, (value, lo, hi) in enumerate(zip(self.pvalues, self.plo, self.phi)):
            if not lo <= value <= hi and self.psrc[i] is not None:
                table, key = parameter_location(spec, self.psrc[i])
                raise self.err(table, key, *domain_message(self.pnames[i], value,
                                                           self.punits[i], lo, hi,
                                                           file_units=True))
        defaults = np.asarray(self.pvalues, dtype=float)
        defaults.setflags(write=False)
        lo, hi = (np.asarray(x, dtype=float) for x in (self.plo, self.phi))
        for a in (lo, hi):
            a.setflags(write=False)
        return Machine(
            spec=spec,
            file=self.file,
            point_names=tuple(self.points),
            link_names=tuple(self.links),
            variable_names=tuple(self.vars),
            variable_units=tuple(self.var_units),
            parameter_names=tuple(self.pnames),
            parameter_units=tuple(self.punits),
            defaults=defaults,
            unit_names=tuple(u.name for u in spec.units),
            unit_types=tuple(u.type for u in spec.units),
            branches=dict(self.branches),
            point_links={k: tuple(v) for k, v in self.point_links.items()},
            program=arr(self.rows, K.UNIT_COLS),
            groups=arr(self.groups, 5),
            unknowns=arr(self.unk, 4),
            terms=arr(self.terms, K.TERM_COLS),
            cams=arr(self.cams, 4),
            arcs=arr(self.arcs, 5),
            kernel_unit_of_row=tuple(self.row_unit),
            cam_designs={k: dict(v) for k, v in self.cam_designs.items()},
            pairs=tuple(self.pairs),
            mass_origins=dict(self.mass_origins),
            parameter_sources=tuple(self.psrc),
            parameter_owner=tuple(self.powner),
            parameter_lo=lo,
            parameter_hi=hi,
            counterweights=counterweights,
        )

    def compile_counterweights(self) -> tuple[Counterweight, ...]:
        """``[counterweights]``: each on a moving link, in its mass frame, with three
        parameters (see :mod:`sewmech.engine.counterweights`)."""
        out = []
        shaft = self.spec.shaft
        for name, cw in self.spec.counterweights.items():
            table = f"counterweights.{name}"
            if cw.link == FRAME or cw.link not in self.links:
                raise self.err(table, "link", *self._not_moving(cw.link, "Give a moving link"))
            origin = self.mass_origins.get(cw.link) or next(
                (p for p in self.points if cw.link in self.point_links[p]), None)
            if origin is None:
                raise self.err(table, "link", f"link '{cw.link}' has no points: a counterweight"
                               " needs its frame (put a point unit on the link)")
            if shaft is not None and cw.link in shaft.links and cw.z_mm is None:
                raise self.err(table, "z_mm", f"'{cw.link}' turns with the upper shaft: the"
                               " bearing reactions need the counterweight's axial plane",
                               "Give z_mm (the same axis as [shaft])")
            src = ("counterweights", name)
            (n0, u0), (n1, u1), (n2, u2) = CW_PARAMETERS[cw.by_moment]
            taken = [f"{name}.{n}" for n in (n0, n1, n2) if f"{name}.{n}" in self.pnames]
            if taken:
                raise self.err(table, "", f"its parameter '{taken[0]}' is already a parameter of"
                               " this machine (a unit or point of the same name)",
                               "Give the counterweight a name of its own")
            if cw.by_moment:
                idx = (self.param(f"{name}.{n0}", cw.static_moment_gcm / 100.0, u0,
                                  src + ("static_moment_gcm",), bounds=(0.0, PARAM_LIMIT)),
                       self.param(f"{name}.{n1}", math.radians(cw.angle_deg), u1,
                                  src + ("angle_deg",)),
                       self.param(f"{name}.{n2}", cw.radius_mm, u2, src + ("radius_mm",),
                                  positive=True))
            else:
                idx = (self.param(f"{name}.{n0}", cw.mass_g / 1000.0, u0, src + ("mass_g",),
                                  bounds=(0.0, PARAM_LIMIT)),
                       self.param(f"{name}.{n1}", cw.at_mm[0], u1, src + ("at_mm", 0)),
                       self.param(f"{name}.{n2}", cw.at_mm[1], u2, src + ("at_mm", 1)))
            z = float("nan") if cw.z_mm is None else float(cw.z_mm)
            out.append(Counterweight(name, cw.link, self.links.index(cw.link), origin, z,
                                     cw.by_moment, idx))
        return tuple(out)

    def dynamics_checks(self):
        """Pairs of the force analysis, mass-frame origins, loads and the shaft table."""
        spec = self.spec
        for table, u, cams in self.contacts:
            for k, c in enumerate(u.contacts):
                key = f"contacts[{k}]"
                if hasattr(c, "cam"):
                    if c.cam not in cams:
                        have = ", ".join(cams) or "none"
                        raise self.err(table, key + ".cam", f"'{c.cam}' is not a loop of this"
                                       f" unit with one cam term (loops with a cam: {have})")
                    row, others, term = cams[c.cam]
                    cam_link = spec.cams[term.cam].link
                    follower = c.follower or term.normal_link
                    if follower is None:
                        raise self.err(table, key + ".follower", "the cam term's normal is an"
                                       " angle variable: name the follower link")
                    self.known_link(table, key + ".follower", follower)
                    trow = self.terms[row]
                    self.pairs.append(Pair(
                        f"{u.name}.{c.cam}", "cam", (cam_link, follower), u.name,
                        line_link=term.normal_link,
                        line_var=term.normal_angle, line_param=trow[7], terms=others,
                        cam_term=row, one_sided=c.one_sided))
                else:
                    self.known_point(table, key + ".slot", c.slot)
                    for lk in ("link", "slot_link"):
                        self.known_link(table, f"{key}.{lk}", getattr(c, lk))
                    if c.link not in self.point_links[c.slot]:
                        raise self.err(table, key + ".link", f"the pin '{c.slot}' is not a point"
                                       f" of link '{c.link}' (it is on:"
                                       f" {', '.join(self.point_links[c.slot])})")
                    self.pairs.append(Pair(
                        f"{c.slot}.slot", "slot", (c.slot_link, c.link), u.name,
                        point=c.slot, line_link=c.slot_link,
                        extra_angle=math.radians(c.slot_deg), one_sided=c.one_sided))
        # every point shared by links is a pin between the first of them and each other one
        for p in self.points:
            links = self.point_links[p]
            for other in links[1:]:
                name = p if len(links) == 2 else f"{p}:{other}"
                self.pairs.append(Pair(name, "revolute", (links[0], other), "", point=p))
        # reading order: by the later of the two links in solve order, driver first
        rank = {"driver": 0, "revolute": 1, "prismatic": 2, "slot": 3, "cam": 4}
        self.pairs.sort(key=lambda p: (max(self.links.index(x) for x in p.links), rank[p.kind]))
        self.mass_origins = {}
        for lname, m in spec.masses.items():
            on = [p for p in self.points if lname in self.point_links[p]]
            if m.origin is not None:
                self.known_point(f"masses.{lname}", "origin", m.origin)
                if m.origin not in on:
                    raise self.err(f"masses.{lname}", "origin", f"'{m.origin}' is not a point of"
                                   f" link '{lname}' (its points: {', '.join(on) or 'none'})")
                self.mass_origins[lname] = m.origin
            elif on:
                self.mass_origins[lname] = on[0]
            else:
                raise self.err(f"masses.{lname}", "origin", f"link '{lname}' has no points; put"
                               " a point unit on it and name its origin here")
        check_loads(spec.machine.name, self.links, self.points, self.point_links, spec.loads,
                    self.file)
        check_conditions(spec.machine.name, self.file, spec.loads, self.points, self.links,
                         self.vars, spec.thread is not None)
        check_springs(spec.machine.name, self.file, spec.springs, spec.torsion_springs,
                      self.links, self.points, self.point_links, self.pairs)
        check_friction(spec.machine.name, self.file, spec.friction, tuple(self.pairs))
        if spec.shaft is not None:
            cranks = {(u.link or u.name): u for u in spec.units if u.type == "crank"}
            pivots = set()
            for lname in spec.shaft.links:
                u = cranks.get(lname)
                if u is None or u.input != SHAFT or u.ratio != 1.0:
                    raise self.err("shaft", f"links.{lname}", f"'{lname}' is not the link of a"
                                   " crank unit turned by the shaft at ratio 1")
                pivots.add(u.pivot)
            if len(pivots) > 1:
                raise self.err("shaft", "links", "the shaft's cranks turn about different"
                               f" points ({', '.join(sorted(pivots))}); they must share one axis")
            pivot = next(iter(pivots))
            missing = [name for name, u in cranks.items() if u.input == SHAFT and u.ratio == 1.0
                       and u.pivot == pivot and name not in spec.shaft.links]
            if missing:
                raise self.err("shaft", "links", f"{', '.join(missing)} turn(s) with the upper"
                               f" shaft (about {pivot} at ratio 1) but have no z here: the"
                               " bearing reactions would leave out their forces",
                               "Give the z (mm) of each one's plane")
            for lname in spec.shaft.links:
                m = spec.masses.get(lname)
                if m is None:
                    continue
                if m.mass is not None and m.inertia is None:
                    raise self.err(f"masses.{lname}", "inertia_zz", f"link '{lname}' turns with"
                                   " the upper shaft ([shaft] links): its bearing reactions need"
                                   " its products of inertia, not only inertia_zz",
                                   "Give the full inertia tensor, or solids")
                if self.mass_origins[lname] != pivot:
                    raise self.err(f"masses.{lname}", "origin", f"link '{lname}' turns with the"
                                   f" upper shaft: its mass frame's origin must be the shaft's"
                                   f" axis point '{pivot}' (it is"
                                   f" '{self.mass_origins[lname]}')", f"Set origin = \"{pivot}\"")

    def unit_crank(self, ui, table, u: CrankUnit):
        pivot = self.known_point(table, "pivot", u.pivot)
        if FRAME not in self.point_links[u.pivot]:
            raise self.err(table, "pivot", f"a crank turns about a frame point; '{u.pivot}' is"
                           " not in [points]")
        link = self.new_link(table, "link", u.link or u.name)
        if u.input == SHAFT:
            setting = -1
        elif u.input in self.inputs:
            setting = self.inputs[u.input]
        else:
            raise self.err(table, "input", f"unknown input '{u.input}'; use 'shaft' or a name"
                           f" from [inputs] ({', '.join(self.inputs) or 'none defined'})")
        lname = self.links[link]
        self.on_link(u.pivot, lname)
        ratio = self.param(f"{u.name}.ratio", u.ratio, "1", ("units", ui, "ratio"))
        self.add_row(ui, [K.OP_CRANK, link, self.param(f"{u.name}.phase",
                                                       math.radians(u.phase_deg), "rad",
                                                       ("units", ui, "phase_deg")),
                          ratio, setting])
        self.pairs.append(Pair(f"{u.name}.torque", "driver", (FRAME, lname), u.name,
                               input=u.input, ratio_param=ratio))
        for pname, (uu, vv) in u.points.items():
            i = self.new_point(table, f"points.{pname}", pname, (lname,))
            src = ("units", ui, "points", pname)
            self.add_row(ui, [K.OP_POINT, i, link, pivot,
                              self.param(f"{pname}.u", uu, "mm", src + (0,)),
                              self.param(f"{pname}.v", vv, "mm", src + (1,))])

    def unit_point(self, ui, table, u: PointUnit):
        link = self.known_link(table, "link", u.link)
        origin = self.known_point(table, "origin", u.origin)
        if u.link not in self.point_links[u.origin]:
            on = [p for p in self.points if u.link in self.point_links.get(p, ())]
            where = f"'{u.origin}' is on {', '.join(self.point_links[u.origin])}"
            if on:
                raise self.err(table, "origin", f"origin '{u.origin}' is not a point of link"
                               f" '{u.link}' ({where}); the points of '{u.link}' solved above"
                               f" this unit are: {', '.join(on)}", "Set origin to one of them,"
                               f" or link to a link '{u.origin}' is on")
            raise self.err(table, "origin", f"origin '{u.origin}' is not a point of link"
                           f" '{u.link}' ({where}); no point of '{u.link}' is solved above this"
                           " unit", f"Solve a point of '{u.link}' first (a loop unit names the"
                           " points its links are pinned at in its joints), or set link to a"
                           f" link '{u.origin}' is on")
        for pname, (uu, vv) in u.points.items():
            i = self.new_point(table, f"points.{pname}", pname, (u.link,))
            src = ("units", ui, "points", pname)
            self.add_row(ui, [K.OP_POINT, i, link, origin,
                              self.param(f"{pname}.u", uu, "mm", src + (0,)),
                              self.param(f"{pname}.v", vv, "mm", src + (1,))])
        for pname, others in u.pins.items():
            if pname not in u.points:
                raise self.err(table, f"pins.{pname}", f"'{pname}' is not one of this unit's"
                               f" points ({', '.join(u.points)})")
            for other in [others] if isinstance(others, str) else others:
                self.known_link(table, f"pins.{pname}", other)
                self.on_link(pname, other)

    def unit_rrr(self, ui, table, u: RRRUnit):
        p1 = self.known_point(table, "joints", u.joints[0])
        p2 = self.known_point(table, "joints", u.joints[1])
        l1 = self.new_link(table, "links", u.links[0])
        l2 = self.new_link(table, "links", u.links[1])
        c = self.new_point(table, "new", u.new, u.links)
        self.on_link(u.joints[0], u.links[0])
        self.on_link(u.joints[1], u.links[1])
        self.branches[u.name] = u.branch
        self.add_row(ui, [K.OP_RRR, p1, p2, c, l1, l2,
                          self.param(f"{u.name}.length1", u.lengths[0], "mm",
                                     ("units", ui, "lengths", 0), positive=True),
                          self.param(f"{u.name}.length2", u.lengths[1], "mm",
                                     ("units", ui, "lengths", 1), positive=True), u.branch])

    def unit_rrp(self, ui, table, u: RRPUnit):
        pin = self.known_point(table, "pin", u.pin)
        gl = self.known_link(table, "guide_link", u.guide_link)
        gp = self.known_point(table, "guide_point", u.guide_point)
        if u.guide_link not in self.point_links[u.guide_point]:
            raise self.err(table, "guide_point", f"guide point '{u.guide_point}' is not on the"
                           f" guide link '{u.guide_link}'")
        rod = self.new_link(table, "rod", u.rod)
        slider = self.new_link(table, "slider", u.slider)
        c = self.new_point(table, "new", u.new, (u.rod, u.slider))
        self.on_link(u.pin, u.rod)
        var = self.new_var(table, "variable", u.variable or u.name, "mm")
        self.branches[u.name] = u.branch
        self.pairs.append(Pair(f"{u.name}.guide", "prismatic", (u.guide_link, u.slider), u.name,
                               point=u.new, line_link=u.slider))
        self.add_row(ui, [K.OP_RRP, pin, gp, gl, c, rod, slider,
                          self.param(f"{u.name}.length", u.length, "mm", ("units", ui, "length"),
                                     positive=True),
                          self.param(f"{u.name}.guide_angle", math.radians(u.guide_angle_deg),
                                     "rad", ("units", ui, "guide_angle_deg")),
                          self.param(f"{u.name}.offset", u.offset, "mm", ("units", ui, "offset")),
                          u.branch, var])

    def unit_rpr(self, ui, table, u: RPRUnit):
        pin = self.known_point(table, "pin", u.pin)
        pivot = self.known_point(table, "pivot", u.pivot)
        link = self.new_link(table, "link", u.link)
        block = self.new_link(table, "block", u.block) if u.block else -1
        self.on_link(u.pivot, u.link)
        if u.block:
            self.on_link(u.pin, u.block)
            self.pairs.append(Pair(f"{u.name}.slot", "prismatic", (u.link, u.block), u.name,
                                   point=u.pin, line_link=u.link))
        else:  # the pin slides in the slot directly: one force normal to the slot
            self.pairs.append(Pair(f"{u.name}.slot", "slot", (u.link, self.point_links[u.pin][0]),
                                   u.name, point=u.pin, line_link=u.link))
        var = self.new_var(table, "variable", u.variable or u.name, "mm")
        self.branches[u.name] = u.branch
        self.add_row(ui, [K.OP_RPR, pin, pivot, link, block,
                          self.param(f"{u.name}.offset", u.offset, "mm", ("units", ui, "offset")),
                          u.branch, var])

    def compile_cam(self, table, name, cam) -> int:
        link = self.known_link(table, "link", cam.link)
        pivot = self.known_point(table, "pivot", cam.pivot)
        if cam.link not in self.point_links[cam.pivot]:
            raise self.err(table, "pivot", f"pivot '{cam.pivot}' is not a point of the cam link"
                           f" '{cam.link}'")
        if cam.constant_width is not None:
            cw = cam.constant_width
            design = {"width": cw.width, "stroke": cw.stroke, "dwell": math.radians(cw.dwell_deg),
                      "orientation": math.radians(cw.orientation_deg)}
            self.cam_designs[name] = design
            built = constant_width_arcs(**design)
            arcs = [(built["cx"][k], built["cy"][k], built["radius"][k],
                     math.degrees(built["normal_from"][k]), math.degrees(built["normal_to"][k]))
                    for k in range(6)]
        else:
            arcs = [(a.center[0], a.center[1], a.radius, a.normal_from_deg, a.normal_to_deg)
                    for a in cam.arcs]
        # the arcs must cover the normal directions once, in order, and join without gaps
        start = arcs[0][3]
        for k, (cx, cy, radius, _, to) in enumerate(arcs):
            nxt = arcs[(k + 1) % len(arcs)]
            frm = nxt[3] + (360.0 if k == len(arcs) - 1 else 0.0)
            if abs(to - frm) > 1e-9:
                raise self.err(table, f"arcs[{k}].normal_to_deg",
                               f"arc {k} ends at normal {to} deg but the next arc starts at"
                               f" {frm} deg; the arcs must cover 360 deg of normal directions"
                               " in order")
            n = np.array([math.cos(math.radians(to)), math.sin(math.radians(to))])
            gap = float(np.hypot(*(np.array([cx, cy]) + radius * n
                                   - np.array(nxt[:2]) - nxt[2] * n)))
            if gap > 1e-6:
                raise self.err(table, f"arcs[{k}]", f"arc {k} and arc {(k + 1) % len(arcs)} do"
                               f" not meet: gap {gap:.3g} mm at their common normal {to} deg")
        if abs(arcs[-1][4] - start - 360.0) > 1e-9:
            raise self.err(table, "arcs", "the arcs must cover exactly 360 deg of normals")
        a0 = len(self.arcs)
        for k, (cx, cy, radius, frm, to) in enumerate(arcs):
            pre = f"{name}.arc{k}"
            src = None if cam.constant_width is not None else ("cams", name, "arcs", k)
            self.arcs.append([self.param(f"{pre}.cx", cx, "mm", src and src + ("center", 0)),
                              self.param(f"{pre}.cy", cy, "mm", src and src + ("center", 1)),
                              self.param(f"{pre}.radius", radius, "mm", src and src + ("radius",),
                                         positive=True),
                              self.param(f"{pre}.normal_from", math.radians(frm), "rad",
                                         src and src + ("normal_from_deg",)),
                              self.param(f"{pre}.normal_to", math.radians(to), "rad",
                                         src and src + ("normal_to_deg",))])
        self.cams.append([link, pivot, a0, len(arcs)])
        self.cam_index[name] = len(self.cams) - 1
        return self.cam_index[name]

    def unit_loop(self, ui, table, u: LoopUnit):
        n_unknown = len(u.unknown_links_deg) + len(u.unknown_lengths_mm) + len(u.unknown_angles_deg)
        if n_unknown != 2 * len(u.loops):
            raise self.err(table, "loops", f"{len(u.loops)} loop(s) give {2 * len(u.loops)}"
                           f" equations but the unit has {n_unknown} unknowns; each loop fixes"
                           " two unknowns")
        u0 = len(self.unk)
        cols: dict[tuple[str, str], int] = {}
        for name, init in u.unknown_links_deg.items():
            li = self.new_link(table, f"unknown_links_deg.{name}", name)
            cols[("link", name)] = len(cols)
            self.unk.append([0, li, 1, self.param(f"{u.name}.init.{name}", math.radians(init),
                                                  "rad", ("units", ui, "unknown_links_deg",
                                                          name))])
        for name, init in u.unknown_lengths_mm.items():
            vi = self.new_var(table, f"unknown_lengths_mm.{name}", name, "mm")
            cols[("len", name)] = len(cols)
            self.unk.append([1, vi, 0, self.param(f"{u.name}.init.{name}", init, "mm",
                                                  ("units", ui, "unknown_lengths_mm", name))])
        for name, init in u.unknown_angles_deg.items():
            vi = self.new_var(table, f"unknown_angles_deg.{name}", name, "rad")
            cols[("ang", name)] = len(cols)
            self.unk.append([1, vi, 1, self.param(f"{u.name}.init.{name}", math.radians(init),
                                                  "rad", ("units", ui, "unknown_angles_deg",
                                                          name))])
        for lname, pts in u.joints.items():
            if ("link", lname) not in cols:
                raise self.err(table, f"joints.{lname}", f"'{lname}' is not an unknown link of"
                               " this unit (unknown_links_deg)")
            for pt in pts:
                self.known_point(table, f"joints.{lname}", pt)
                self.on_link(pt, lname)
        used: set[int] = set()
        t0 = len(self.terms)
        for li, loop in enumerate(u.loops):
            for ti, term in enumerate(loop.terms):
                key = f"loops[{li}].terms[{ti}]"
                pre = f"{u.name}.{loop.name}.{ti}"
                tsrc = ("units", ui, "loops", li, "terms", ti)
                row = [0] * K.TERM_COLS
                row[1] = li
                row[2] = term.sign
                row[7] = row[9] = row[10] = row[11] = -1
                row[8] = -1
                kind = term.kind
                if kind == "point":
                    row[0] = K.TERM_POINT
                    row[4] = self.known_point(table, key + ".point", term.point)
                    self.terms.append(row)
                    continue
                if kind in ("link", "angle"):
                    row[0] = K.TERM_VEC
                    # length
                    if isinstance(term.length, str):
                        if ("len", term.length) in cols:
                            row[10] = cols[("len", term.length)]
                            row[4] = self.vars.index(term.length)
                        elif term.length in self.vars and self.var_units[
                                self.vars.index(term.length)] == "mm":
                            row[4] = self.vars.index(term.length)
                        else:
                            raise self.err(table, key + ".length", f"'{term.length}' is neither"
                                           " a length unknown of this unit nor a known slider"
                                           " variable")
                        row[3] = K.SRC_VAR
                    else:
                        row[3] = K.SRC_PARAM
                        row[4] = self.param(f"{pre}.length", term.length, "mm",
                                            tsrc + ("length",), positive=True)
                    if kind == "link":
                        self._angle_source(table, key + ".link", row, cols, term.link, "link")
                    else:
                        self._angle_source(table, key + ".angle", row, cols, term.angle, "angle")
                    if term.angle_deg != 0.0:
                        row[7] = self.param(f"{pre}.angle", math.radians(term.angle_deg), "rad",
                                            tsrc + ("angle_deg",))
                else:
                    row[0] = K.TERM_CAM
                    if term.cam not in self.spec.cams:
                        raise self.err(table, key + ".cam", f"unknown cam '{term.cam}'; define it"
                                       f" in [cams] ({', '.join(self.spec.cams) or 'none'})")
                    if term.cam not in self.cam_index:
                        self.compile_cam(f"cams.{term.cam}", term.cam, self.spec.cams[term.cam])
                    row[8] = self.cam_index[term.cam]
                    cam_link = self.spec.cams[term.cam].link
                    if ("link", cam_link) in cols:
                        raise self.err(table, key + ".cam", f"the cam's link '{cam_link}' must be"
                                       " moved by an earlier unit, not be an unknown here")
                    if term.normal_link is not None:
                        self._angle_source(table, key + ".normal_link", row, cols,
                                           term.normal_link, "link")
                    else:
                        self._angle_source(table, key + ".normal_angle", row, cols,
                                           term.normal_angle, "angle")
                    if term.normal_deg != 0.0:
                        row[7] = self.param(f"{pre}.normal", math.radians(term.normal_deg),
                                            "rad", tsrc + ("normal_deg",))
                    if term.offset != 0.0:
                        row[9] = self.param(f"{pre}.offset", term.offset, "mm",
                                            tsrc + ("offset",))
                used.update(c for c in (row[10], row[11]) if c >= 0)
                self.terms.append(row)
        names = list(cols)
        for c, (kind, name) in enumerate(names):
            if c not in used:
                raise self.err(table, "loops", f"unknown '{name}' appears in no loop term; the"
                               " loop equations cannot determine it")
        cams = {}  # loop name -> (cam term row, rows of the loop's other terms, follower)
        for li, loop in enumerate(u.loops):
            rows = [t for t in range(t0, len(self.terms)) if self.terms[t][1] == li]
            cam_rows = [t for t in rows if self.terms[t][0] == K.TERM_CAM]
            if len(cam_rows) == 1:
                ct = loop.terms[rows.index(cam_rows[0])]
                cams[loop.name] = (cam_rows[0], tuple(t for t in rows if t != cam_rows[0]), ct)
        self.contacts.append((table, u, cams))
        g = len(self.groups)
        self.groups.append([n_unknown, u0, 0, t0, len(self.terms) - t0])
        self.add_row(ui, [K.OP_LOOP, g])

    def _angle_source(self, table, key, row, cols, name, kind):
        if kind == "link":
            row[5] = K.SRC_LINK
            if ("link", name) in cols:
                row[6] = self.links.index(name)
                row[11] = cols[("link", name)]
            else:
                row[6] = self.known_link(table, key, name)
        else:
            row[5] = K.SRC_VAR
            if ("ang", name) in cols:
                row[6] = self.vars.index(name)
                row[11] = cols[("ang", name)]
            elif name in self.vars and self.var_units[self.vars.index(name)] == "rad":
                row[6] = self.vars.index(name)
            else:
                raise self.err(table, key, f"'{name}' is neither an angle unknown of this unit"
                               " nor a known angle variable")


def compile_machine(spec: MachineSpec, file: str = "<string>") -> Machine:
    """Resolve names and build the index arrays of a machine (see :class:`Machine`)."""
    return _Compiler(spec, file).compile()


def shipped_machines() -> dict[str, Path]:
    """Machine files shipped with sewmech: name -> path."""
    root = resources.files(MACHINES_PACKAGE)
    return {Path(p.name).stem: Path(str(p)) for p in root.iterdir() if p.name.endswith(".toml")}


def load_machine(name_or_path: str | Path) -> Machine:
    """Load and compile a machine file by path, or a shipped machine by name (``"jb1-3"``).

    The argument is a path first: a file of that name in the working directory (even without
    ``.toml``) is read instead of the shipped machine of the same name; a directory of that
    name (an output directory ``jb8-2/``, say) is not a machine file and does not hide it."""
    path = user_path(name_or_path)
    shipped = shipped_machines()
    if str(name_or_path) in shipped and not path.is_file():
        path = shipped[str(name_or_path)]
    elif not path.exists():
        known = ", ".join(sorted(shipped))
        raise MachineFileError(str(name_or_path), "", "", "no such file and no shipped machine of"
                               f" that name; shipped machines: {known}")
    return compile_machine(load_machine_spec(path), str(path))


def machine_from_toml(text: str, file: str = "<string>") -> Machine:
    """Parse and compile machine-file text."""
    return compile_machine(parse_machine(text, file), file)
