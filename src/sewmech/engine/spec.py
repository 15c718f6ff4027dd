"""Machine files: TOML text -> typed, validated, frozen :class:`MachineSpec`.

Only structure and value ranges are checked here (unknown keys, types, positive lengths,
branches of +1/-1). Name resolution (unknown points, a unit that uses a point not yet solved)
happens once in :func:`sewmech.machine.compile_machine`, which raises the same
:class:`~sewmech.errors.MachineFileError` with file, table and key.

The format is documented in ``docs/machine-files.md``. Lengths are mm, angles degrees (keys end
in ``_deg``), speeds rpm.
"""

from __future__ import annotations

import math
import re
import tomllib
import types
import typing
from pathlib import Path
from typing import Annotated, Literal, Union

from pydantic import (
    BaseModel,
    BeforeValidator,
    ConfigDict,
    Field,
    Strict,
    ValidationError,
    field_validator,
    model_validator,
)

from .errors import MachineFileError
from .paths import not_regular, user_path

NAME_RE = re.compile(r"^[A-Za-z_][A-Za-z0-9_.\-]*$")
FRAME = "frame"
SHAFT = "shaft"

Name = Annotated[str, Field(pattern=NAME_RE.pattern, min_length=1)]
# numbers and flags are taken as TOML gives them: a quoted "38.0" or a true is not a number,
# and a 1 is not a flag (pydantic would convert them silently)
Float = Annotated[float, Strict()]
PosFloat = Annotated[float, Strict(), Field(gt=0.0)]
NonNegFloat = Annotated[float, Strict(), Field(ge=0.0)]
Int = Annotated[int, Strict()]
Bool = Annotated[bool, Strict()]
Branch = Literal[1, -1]
Vec2 = tuple[Float, Float]


#: the largest magnitude of any number in a machine file (mm, deg, kg, N, rpm ...): far beyond
#: any machine, and far from overflow in the squares and products of the kernels
NUMBER_LIMIT = 1e9


class ValueHint(ValueError):
    """A validator's ValueError that also says what to do: the :class:`MachineFileError` made
    from it carries ``hint`` (every file sewmech reads, :func:`validate_model`)."""

    def __init__(self, message: str, hint: str = ""):
        super().__init__(message)
        self.hint = hint


def _too_large(value, path: str):
    """The first number in ``value`` (a number or nested tuples/lists/dicts of them) beyond
    NUMBER_LIMIT, as (path, value); None if there is none."""
    if isinstance(value, float | int) and not isinstance(value, bool):
        return (path, value) if abs(value) > NUMBER_LIMIT else None
    if isinstance(value, tuple | list):
        items = enumerate(value)
    elif isinstance(value, dict):
        items = value.items()
    else:
        return None
    for k, v in items:
        hit = _too_large(v, f"{path}[{k}]" if isinstance(k, int) else f"{path}.{k}")
        if hit is not None:
            return hit
    return None


class _Spec(BaseModel):
    # every number of a file must be finite: nan and inf are refused where they are read
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=False)

    @model_validator(mode="after")
    def _bounded(self):
        for name in type(self).model_fields:
            hit = _too_large(getattr(self, name), name)
            if hit is not None:
                raise ValueError(f"{hit[0]} = {hit[1]:g} is beyond +-{NUMBER_LIMIT:g}: numbers"
                                 " in machine files are mm, deg, kg, N, rpm; check the value")
        return self


def _local_point(value):
    """A point in a link frame: ``[u, v]`` (mm) or ``{ length = mm, angle_deg = deg }`` (polar,
    from the link's u axis, counter-clockwise), read as (u, v)."""
    if isinstance(value, dict):
        if set(value) != {"length", "angle_deg"}:
            raise ValueError("a local point is [u, v] (mm in the link frame) or"
                             " { length = mm, angle_deg = deg }; got the keys"
                             f" {sorted(value)}")
        r, a = value["length"], value["angle_deg"]
        for key, x in (("length", r), ("angle_deg", a)):
            if isinstance(x, bool) or not isinstance(x, (int, float)) or not math.isfinite(x):
                raise ValueError(f"{key} of a polar local point must be a finite number,"
                                 f" got {x!r}")
        return (r * math.cos(math.radians(a)), r * math.sin(math.radians(a)))
    if not isinstance(value, (list, tuple)) or len(value) != 2:
        raise ValueError("a local point is [u, v] (mm in the link frame) or"
                         f" {{ length = mm, angle_deg = deg }}; got {value!r}")
    return value


LocalPoint = Annotated[Vec2, BeforeValidator(_local_point)]


class MachineInfo(_Spec):
    """``[machine]``: identity of the machine."""

    name: Name
    title: str = ""
    description: str = ""
    format: Literal[1] = 1  # the version of the file format
    length_unit: Literal["mm"] = "mm"  # every length of the file is in mm
    variants: list[str] = Field(default_factory=list)  # machines the report compares with


class Convention(_Spec):
    """``[convention]``: what the shaft angle means.

    ``reference_phi_deg`` is the shaft angle at which ``reference_event`` happens (e.g. 90 with
    the needle bar at its top, as in the JB dynamics report). Loop units are assembled from
    their initial guesses at ``assembly_phi_deg`` (default: the reference angle) and continued
    forward from there.
    """

    reference_event: str
    reference_phi_deg: Float
    description: str = ""
    assembly_phi_deg: Float | None = None
    # what makes the reference event checkable (``sewmech check`` proves it): a point at an
    # extreme of its travel, or a link at an angle
    reference_point: Name | None = None
    reference_extreme: Literal["top", "bottom", "left", "right"] | None = None
    reference_link: Name | None = None
    reference_angle_deg: Float | None = None

    @model_validator(mode="after")
    def _checkable(self):
        if (self.reference_point is None) != (self.reference_extreme is None):
            raise ValueError("reference_point and reference_extreme go together: the point and"
                             " where it is at the reference event (top, bottom, left, right)")
        if (self.reference_link is None) != (self.reference_angle_deg is None):
            raise ValueError("reference_link and reference_angle_deg go together: the link and"
                             " its angle (deg, from +x) at the reference event")
        if self.reference_point is not None and self.reference_link is not None:
            raise ValueError("give reference_point/reference_extreme or"
                             " reference_link/reference_angle_deg, not both")
        return self


class Speed(_Spec):
    """``[speed]``: working speed of the upper shaft."""

    rpm: Annotated[Float, Field(ge=1e-3, le=1e5)] = 1000.0  # (kinematics.MIN_RPM, MAX_RPM)
    note: str = ""


class SewingSpec(_Spec):
    """``[sewing]``: which parts of the machine do which job in stitch formation.

    The timing checks, the timing diagram and the report read the machine through these roles,
    so they work for any lockstitch machine file. Heights are frame y, mm.
    """

    plate_y: Float  # top surface of the throat plate, mm
    fabric_thickness: NonNegFloat = 1.0  # mm, for the "needle in fabric" window
    needle_point: Name
    needle_eye: Name
    take_up_eye: Name | None = None
    shuttle_link: Name | None = None  # the link that carries the shuttle (hook) point
    shuttle_point: Name | None = None
    hook_crank: Name | None = None  # the crank unit on the upper shaft that drives the hook
    feed_dog: Name | None = None  # the feed dog's tooth-tip point
    regulator: Name | None = None  # the stitch-regulator input
    feed_cam: Name | None = None  # the crank unit that turns the feed cam on the upper shaft
    forward: Literal["+x", "-x"] = "+x"  # direction the dog moves the fabric in forward feed
    # structural parameters of the feed for the sensitivity study: label -> parameter names
    # changed together (one physical dimension may appear in several loop terms)
    feed_parameters: dict[str, list[str]] = Field(default_factory=dict)
    note: str = ""


class PointSpec(_Spec):
    """``[points.NAME]``: a point fixed on the frame, mm."""

    x: Float
    y: Float
    note: str = ""


class InputSpec(_Spec):
    """``[inputs.NAME]``: a setting input such as the stitch-length regulator angle, degrees."""

    default_deg: Float = 0.0
    min_deg: Float | None = None
    max_deg: Float | None = None
    note: str = ""

    @model_validator(mode="after")
    def _range(self):
        if self.min_deg is not None and self.max_deg is not None and self.min_deg > self.max_deg:
            raise ValueError(f"min_deg {self.min_deg} is larger than max_deg {self.max_deg}")
        if self.min_deg is not None and self.default_deg < self.min_deg or (
                self.max_deg is not None and self.default_deg > self.max_deg):
            raise ValueError(f"default_deg {self.default_deg} is outside min_deg .. max_deg"
                             f" ({self.min_deg} .. {self.max_deg})")
        return self


class CrankUnit(_Spec):
    """A driver link rotating about a frame point: theta = phase + ratio * phi (or a setting)."""

    type: Literal["crank"]
    name: Name
    link: Name | None = None
    pivot: Name
    phase_deg: Float = 0.0
    ratio: Float = 1.0
    input: Name = SHAFT
    points: dict[Name, LocalPoint] = Field(default_factory=dict)
    note: str = ""

    @model_validator(mode="after")
    def _turns(self):
        if self.input == SHAFT and self.ratio == 0.0:
            raise ValueError("ratio = 0: the shaft would not turn this crank; give its speed"
                             " ratio to the shaft (1: turns with it, 2: twice as fast, -1: the"
                             " other way)")
        return self


class PointUnit(_Spec):
    """Points fixed on a moving link, local (u, v) mm in the link frame from a known origin."""

    type: Literal["point"]
    name: Name
    link: Name
    origin: Name
    points: dict[Name, LocalPoint] = Field(min_length=1)
    # new points of this unit where other (already moved) links are pinned: revolute joints
    # for the force analysis, e.g. a fork hung on a rock-shaft arm inside a loop unit
    pins: dict[Name, Name | list[Name]] = Field(default_factory=dict)
    note: str = ""


class RRRUnit(_Spec):
    """Two-link dyad: links[0] of lengths[0] from joints[0], links[1] from joints[1], meet at new."""

    type: Literal["rrr"]
    name: Name
    joints: tuple[Name, Name]
    new: Name
    links: tuple[Name, Name]
    lengths: tuple[PosFloat, PosFloat]
    branch: Branch
    note: str = ""

    @model_validator(mode="after")
    def _distinct(self):
        if self.joints[0] == self.joints[1]:
            raise ValueError(f"joints: the two joints must be different points (both are"
                             f" '{self.joints[0]}')")
        if self.links[0] == self.links[1]:
            raise ValueError(f"links: the two links must be different (both are"
                             f" '{self.links[0]}')")
        if self.new in self.joints:
            raise ValueError(f"new: '{self.new}' is one of the joints; name the new joint")
        return self


class RRPUnit(_Spec):
    """Slider dyad: rod from pin to a slider on a guide line of guide_link (frame or moving)."""

    type: Literal["rrp"]
    name: Name
    pin: Name
    rod: Name
    length: PosFloat
    new: Name
    slider: Name
    guide_point: Name
    guide_link: Name = FRAME
    guide_angle_deg: Float = 90.0
    offset: Float = 0.0
    variable: Name | None = None
    branch: Branch
    note: str = ""


class RPRUnit(_Spec):
    """Rotating guide: the slot of link (pivoting at pivot) passes through a block pinned at pin."""

    type: Literal["rpr"]
    name: Name
    pin: Name
    pivot: Name
    link: Name
    offset: Float = 0.0
    block: Name | None = None
    variable: Name | None = None
    branch: Branch
    note: str = ""


class LoopTerm(_Spec):
    """One vector of a loop: exactly one of point, link, angle, cam.

    - ``{point = "A"}``: the position of a known point;
    - ``{link = "L", length = 12.0, angle_deg = 0}``: length * e^{i(theta_L + angle)};
      ``length`` may name a length unknown of the unit (a slider variable);
    - ``{angle = "psi", length = ...}``: as above with a free angle unknown;
    - ``{cam = "C", normal_link = "L" | normal_angle = "psi", normal_deg = 90, offset = 0}``:
      the point of cam C's profile whose outward normal points along the given direction,
      pushed out by ``offset`` (a roller radius).
    """

    point: Name | None = None
    link: Name | None = None
    angle: Name | None = None
    cam: Name | None = None
    length: PosFloat | Name | None = None
    angle_deg: Float = 0.0
    normal_link: Name | None = None
    normal_angle: Name | None = None
    normal_deg: Float = 0.0
    offset: Float = 0.0
    sign: Literal[1, -1] = 1

    @model_validator(mode="after")
    def _one_kind(self):
        kinds = [k for k in ("point", "link", "angle", "cam") if getattr(self, k) is not None]
        if len(kinds) != 1:
            raise ValueError(
                "a loop term needs exactly one of 'point', 'link', 'angle', 'cam'"
                f" (found {kinds or 'none'})"
            )
        kind = kinds[0]
        if kind in ("link", "angle") and self.length is None:
            raise ValueError(f"a '{kind}' term needs 'length' (mm, or a length unknown's name)")
        if kind == "cam" and (self.normal_link is None) == (self.normal_angle is None):
            raise ValueError("a 'cam' term needs exactly one of 'normal_link', 'normal_angle'")
        return self

    @property
    def kind(self) -> str:
        for k in ("point", "link", "angle", "cam"):
            if getattr(self, k) is not None:
                return k
        raise AssertionError


class Loop(_Spec):
    """A closed vector loop: the terms sum to zero."""

    name: Name
    terms: list[LoopTerm] = Field(min_length=2)


class CamContact(_Spec):
    """A cam pair of a loop unit: the force acts along the cam term's normal.

    ``cam`` names a loop of the unit that has a cam term; ``follower`` is the link the cam
    pushes (default: the term's ``normal_link``).
    """

    cam: Name
    follower: Name | None = None
    one_sided: Bool = False  # a contact that can only push (a cam under a pad): it opens at N < 0
    margin_N: NonNegFloat = 1.0  # one-sided: the least force it must keep (its check)


class SlotContact(_Spec):
    """A pin sliding in a slot (a massless block), or a roller on a flat face: one force,
    normal to the slot line, through the pin point.

    ``slot`` is the pin (roller centre) point, ``link`` the link that carries it, and the slot
    line runs along ``slot_link``'s angle turned by ``slot_deg``.
    """

    slot: Name
    link: Name
    slot_link: Name
    slot_deg: Float = 0.0
    one_sided: Bool = False  # a roller on one flat face only: it lifts off at N < 0
    margin_N: NonNegFloat = 1.0  # one-sided: the least force it must keep (its check)


class LoopUnit(_Spec):
    """Unknowns solved together by Newton-Raphson on vector loop-closure equations."""

    type: Literal["loop"]
    name: Name
    unknown_links_deg: dict[Name, Float] = Field(default_factory=dict)
    unknown_lengths_mm: dict[Name, Float] = Field(default_factory=dict)
    unknown_angles_deg: dict[Name, Float] = Field(default_factory=dict)
    # known points that an unknown link is pinned at (e.g. a rocker's frame pivot): later
    # `point` units may use them as origins on that link
    joints: dict[Name, list[Name]] = Field(default_factory=dict)
    loops: list[Loop] = Field(min_length=1)
    # pairs inside the loops that are not revolute joints (the force analysis cannot read them
    # off the loop terms): cam contacts and pins in slots
    contacts: list[CamContact | SlotContact] = Field(default_factory=list)
    note: str = ""


Unit = Annotated[
    Union[CrankUnit, PointUnit, RRRUnit, RRPUnit, RPRUnit, LoopUnit], Field(discriminator="type")
]


class CamArc(_Spec):
    """One circular arc of a cam profile in the cam link's frame (origin at the pivot).

    ``normal_from_deg`` .. ``normal_to_deg``: the range of outward-normal directions the arc
    covers, degrees in the cam frame, counter-clockwise.
    """

    center: Vec2
    radius: PosFloat
    normal_from_deg: Float
    normal_to_deg: Float

    @model_validator(mode="after")
    def _range(self):
        if not self.normal_to_deg > self.normal_from_deg:
            raise ValueError("normal_to_deg must be larger than normal_from_deg (counter-clockwise)")
        return self


class ConstantWidthSpec(_Spec):
    """``constant_width = {...}``: the six-arc constant-width dwell cam of a feed fork
    (see :mod:`sewmech.cams`)."""

    width: PosFloat  # gap between the fork's faces, mm
    stroke: NonNegFloat  # fork travel between the dwells, mm
    dwell_deg: Annotated[Float, Field(ge=0.0, lt=180.0)]  # rest at each end of the stroke
    orientation_deg: Float = 0.0  # cam-frame normal at the middle of the inner dwell

    @model_validator(mode="after")
    def _convex(self):
        from .cams import constant_width_arcs

        if self.stroke >= self.width:
            raise ValueError(f"stroke {self.stroke} mm must be smaller than width {self.width} mm")
        constant_width_arcs(self.width, self.stroke, math.radians(self.dwell_deg))
        return self


class CamSpec(_Spec):
    """``[cams.NAME]``: a convex cam made of circular arcs, fixed on a link turning about pivot.

    Give either the arcs or ``constant_width`` (the arcs are then built from its design values).
    """

    link: Name
    pivot: Name
    arcs: list[CamArc] | None = Field(default=None, min_length=1)
    constant_width: ConstantWidthSpec | None = None
    note: str = ""

    @model_validator(mode="after")
    def _one_profile(self):
        if (self.arcs is None) == (self.constant_width is None):
            raise ValueError("a cam needs exactly one of 'arcs' and 'constant_width'")
        return self


class GuideSpec(_Spec):
    """One thread guide: a point the thread passes through, or a pin it wraps."""

    point: Name
    radius: NonNegFloat = 0.0  # mm; 0: a hole or eye
    wrap: Literal["ccw", "cw"] = "ccw"  # the thread's turn round a pin, seen from the hand wheel
    note: str = ""


class AdjustSpec(_Spec):
    """``[thread.adjust]``: the take-up's adjustable dimension (a parameter name, e.g. the
    rocker pivot's height on an eccentric stud) and its range, internal units (mm or rad)."""

    parameter: str
    min: Float
    max: Float
    note: str = ""

    @model_validator(mode="after")
    def _range(self):
        if not self.max > self.min:
            raise ValueError(f"max {self.max} must be larger than min {self.min}")
        return self


class ThreadSpec(_Spec):
    """``[thread]``: the needle thread's path from the tension discs to the needle eye."""

    guides: list[GuideSpec] = Field(min_length=2)
    # indices of the guides that bound the take-up section (its supply), both point guides
    take_up: tuple[Int, Int]
    thread_diameter: NonNegFloat = 0.0  # mm
    bobbin_case_radius: PosFloat | None = None  # mm, about the shuttle axis: the loop's way
    # shuttle turn from seizure to casting the loop off
    cast_off_deg: Annotated[PosFloat, Field(le=360.0)] = 180.0
    adjust: AdjustSpec | None = None
    note: str = ""

    @model_validator(mode="after")
    def _sections(self):
        n = len(self.guides)
        i0, i1 = self.take_up
        if not 0 <= i0 < i1 < n:
            raise ValueError(f"take_up must be two guide indices 0 <= first < second < {n},"
                             f" got {list(self.take_up)}")
        for k in (0, n - 1, i0, i1):
            if self.guides[k].radius != 0.0:
                raise ValueError(f"guide {k} ('{self.guides[k].point}') bounds a section of the"
                                 " path and must be a point guide (radius 0)")
        return self


Vec3 = tuple[Float, Float, Float]


class _SolidBase(_Spec):
    hole: Bool = False  # a negative solid (bore, pocket)
    material: str | None = None  # this solid's own material (default: the link's)
    density: PosFloat | None = None  # or density, kg/m^3
    note: str = ""


class CylinderSolid(_SolidBase):
    type: Literal["cylinder"]
    radius: PosFloat
    length: PosFloat
    base: Vec3 = (0.0, 0.0, 0.0)  # centre of one end face, mm (link frame u, v, z)
    axis: Vec3 = (0.0, 0.0, 1.0)


class TubeSolid(_SolidBase):
    type: Literal["hollow_cylinder"]
    r_out: PosFloat
    r_in: NonNegFloat
    length: PosFloat
    base: Vec3 = (0.0, 0.0, 0.0)
    axis: Vec3 = (0.0, 0.0, 1.0)


class FrustumSolid(_SolidBase):
    type: Literal["frustum", "cone"]
    r1: PosFloat  # radius at the base
    r2: NonNegFloat = 0.0  # radius at the far end (0: a cone)
    height: PosFloat
    base: Vec3 = (0.0, 0.0, 0.0)
    axis: Vec3 = (0.0, 0.0, 1.0)


class BoxSolid(_SolidBase):
    type: Literal["box"]
    size: tuple[PosFloat, PosFloat, PosFloat]  # edges along u, v, z, mm
    center: Vec3 = (0.0, 0.0, 0.0)
    angle_deg: Float = 0.0  # turn about z


class SphereSolid(_SolidBase):
    type: Literal["sphere"]
    radius: PosFloat
    center: Vec3 = (0.0, 0.0, 0.0)


class PointSolid(_SolidBase):
    type: Literal["point"]
    mass: PosFloat  # kg
    at: Vec3 = (0.0, 0.0, 0.0)


Solid = Annotated[Union[CylinderSolid, TubeSolid, FrustumSolid, BoxSolid, SphereSolid,
                        PointSolid], Field(discriminator="type")]


class MassSpec(_Spec):
    """``[masses.LINK]``: a link's mass properties in its own frame (u along the link, v to its
    left, z along the shafts), mm and kg: measured values (``mass``, ``com``, ``inertia_zz``
    or a full ``inertia`` tensor, kg mm^2 about the centre of mass), or ``solids`` with a
    ``material`` or ``density`` (kg/m^3)."""

    mass: PosFloat | None = None
    com: tuple[Float, Float] | Vec3 | None = None
    inertia_zz: NonNegFloat | None = None
    inertia: tuple[Vec3, Vec3, Vec3] | None = None
    solids: list[Solid] | None = None
    material: str | None = None
    density: PosFloat | None = None
    origin: Name | None = None  # the point at the frame's origin (default: the link's first)
    note: str = ""

    @model_validator(mode="after")
    def _one_way(self):
        measured = self.mass is not None
        if measured == (self.solids is not None):
            raise ValueError("give either measured values (mass, com, inertia_zz or inertia) or"
                             " solids, not both and not neither")
        if measured:
            if self.com is None or (self.inertia_zz is None) == (self.inertia is None):
                raise ValueError("measured mass properties need com and exactly one of"
                                 " inertia_zz, inertia")
        else:
            if not self.solids:  # (mass.compose() refused it later, by its own name)
                raise ValueHint("solids = [] holds no solid: a part is made of at least one",
                                "List its solids (box, cylinder, ...; docs/machine-files.md),"
                                " or give its measured mass, com and inertia_zz")
            if (self.material is None) == (self.density is None):
                raise ValueError("solids need exactly one of material, density")
            from .mass import MATERIALS

            for k, solid in enumerate([self] + list(self.solids)):
                if solid.material is not None and solid.material not in MATERIALS:
                    where = "" if k == 0 else f"solids[{k - 1}]: "
                    raise ValueError(f"{where}unknown material '{solid.material}'; known:"
                                     f" {', '.join(sorted(MATERIALS))} (or give density)")
                if k and solid.material is not None and solid.density is not None:
                    raise ValueError(f"solids[{k - 1}]: give material or density, not both")
        return self


class CounterweightSpec(_Spec):
    """``[counterweights.NAME]``: a point mass added to a moving link (a counterweight, or the
    extra one the balancing chooses), in the frame of the link's ``[masses]`` table (its origin
    point, u along the link, v to its left; the link's first point when it has no table).

    Two ways to give it: ``mass_g`` at ``at_mm = [u, v]``, or its static moment
    ``static_moment_gcm`` (S = m * r, g cm) at ``angle_deg`` (from u, counter-clockwise) and
    ``radius_mm`` (r). ``z_mm``: its axial plane, needed on a link that turns with the upper
    shaft (``[shaft] links``) for the bearing reactions; ``max_static_moment_gcm``: the most
    the space allows, a limit for the balancing; ``bore_mm``: the diameter of the shaft it is
    clamped on, for the recipe of a built counterweight (default: the link's own solid on its
    axis at ``z_mm``). The file's ``[masses]`` stay as they
    are; a counterweight is an addition, and each of its values is a parameter
    (``NAME.mass``, ``NAME.u``, ``NAME.v`` or ``NAME.static_moment``, ``NAME.angle``,
    ``NAME.radius``) that ``--set``, sweeps and the balancing change.
    """

    link: Name
    mass_g: NonNegFloat | None = None
    at_mm: LocalPoint | None = None
    static_moment_gcm: NonNegFloat | None = None
    angle_deg: Float | None = None
    radius_mm: PosFloat | None = None
    z_mm: Float | None = None
    max_static_moment_gcm: PosFloat | None = None
    bore_mm: PosFloat | None = None
    note: str = ""

    @model_validator(mode="after")
    def _one_way(self):
        by_mass = (self.mass_g, self.at_mm)
        by_moment = (self.static_moment_gcm, self.angle_deg, self.radius_mm)
        if all(x is not None for x in by_mass) and all(x is None for x in by_moment):
            return self
        if all(x is not None for x in by_moment) and all(x is None for x in by_mass):
            return self
        raise ValueError("give either mass_g and at_mm = [u, v], or static_moment_gcm,"
                         " angle_deg and radius_mm (one way, complete)")

    @property
    def by_moment(self) -> bool:
        return self.static_moment_gcm is not None


#: the largest process load, N: ten tonnes, far beyond any force a sewing machine's process
#: puts on it (its presser foot about 15 N, the needle through thick material a few hundred)
MAX_LOAD_N = 1e5


class Condition(_Spec):
    """One clause of a load's ``when``: a channel of the machine's motion (a kinematics
    channel such as ``p_feed_dog.tip_y``, or a thread channel such as
    ``thread.take_up_mm``) above or below a value (in the channel's unit), rising or falling
    (the sign of its rate), or within ``within_of_max`` of its largest value over the turn."""

    channel: str = Field(min_length=1, max_length=200)
    above: Float | None = None
    below: Float | None = None
    rising: Bool | None = None
    falling: Bool | None = None
    within_of_max: NonNegFloat | None = None

    @model_validator(mode="after")
    def _one(self):
        given = [k for k in ("above", "below", "rising", "falling", "within_of_max")
                 if getattr(self, k) is not None]
        if len(given) != 1:
            raise ValueHint(f"a condition needs exactly one of above, below, rising, falling"
                            f" and within_of_max, got {', '.join(given) or 'none'}",
                            "Write e.g. { channel = \"p_feed_dog.tip_y\", above = -140.0 }")
        if (self.rising is False) or (self.falling is False):
            raise ValueHint("rising and falling take true", "Write rising = true, or the"
                            " opposite clause (falling = true)")
        return self


class LoadSpec(_Spec):
    """``[[loads]]``: a process force on a point of a link while the shaft angle is inside one
    of its windows (degrees in the machine's convention; a window may wrap through 360) and
    every condition of ``when`` holds (docs/dynamics.md).

    The direction is fixed in the frame (``angle_deg``, counter-clockwise from +x) or along the
    resultant of unit vectors from the point ``toward`` other points (a thread that runs over
    the point to two guides pulls along the bisector of its legs). The force law ``law``:
    ``constant`` (``force_N``), ``elastic`` (``force_N`` plus ``rate_N_per_mm`` times the travel
    of the first above/below condition's channel past its threshold: the presser foot lifted by
    the dog through the fabric) or ``resistive`` (``force_N`` against the point's velocity,
    along the line ``angle_deg`` if given: the fabric's feed resistance; a smooth sign below
    ``smooth_mm_s``).
    """

    name: str
    link: Name
    point: Name
    force_N: Float
    angle_deg: Float | None = None
    toward: list[Name] | None = Field(default=None, min_length=1)
    windows_deg: list[tuple[Float, Float]] = Field(default_factory=lambda: [(0.0, 360.0)],
                                                   min_length=1)
    when: list[Condition] = Field(default_factory=list)
    law: Literal["constant", "elastic", "resistive"] = "constant"
    rate_N_per_mm: NonNegFloat | None = None
    smooth_mm_s: PosFloat = 1.0
    note: str = ""

    @field_validator("when", mode="before")
    @classmethod
    def _one_or_many(cls, v):
        return [v] if isinstance(v, dict) else v

    @field_validator("force_N")
    @classmethod
    def _force(cls, v):
        if not abs(v) <= MAX_LOAD_N:  # (a NaN is refused before: allow_inf_nan)
            raise ValueHint(f"a process load must be within +-{MAX_LOAD_N:g} N",
                            "Give the force in N (a presser foot's is about 15 N, the needle's"
                            " through thick material a few hundred)")
        return v

    @model_validator(mode="after")
    def _direction(self):
        if self.law == "resistive":
            if self.toward is not None:
                raise ValueError("a resistive load acts against its point's velocity: give no"
                                 " toward (angle_deg, if given, is the line it acts along)")
        elif (self.angle_deg is None) == (self.toward is None):
            raise ValueError("a load needs exactly one of angle_deg (a fixed direction) and"
                             " toward (points its line of action is pulled towards)")
        if self.law == "elastic":
            if self.rate_N_per_mm is None:
                raise ValueHint("an elastic load needs rate_N_per_mm, the force it gains per mm"
                                " of travel", "Give e.g. rate_N_per_mm = 2.0")
            if not any(c.above is not None or c.below is not None for c in self.when):
                raise ValueHint("an elastic load needs a when condition with above or below:"
                                " its travel is counted from that threshold",
                                "Give e.g. when = { channel = \"p_feed_dog.tip_y\","
                                " above = -140.0 }")
        elif self.rate_N_per_mm is not None:
            raise ValueHint(f"rate_N_per_mm is for an elastic load, this one is {self.law}",
                            "Write law = \"elastic\", or leave rate_N_per_mm out")
        if self.law != "constant" and self.force_N < 0.0:
            raise ValueHint(f"an {self.law} load's force_N is a magnitude (>= 0), got"
                            f" {self.force_N:g}", "Give it >= 0; the law gives its direction")
        for a, b in self.windows_deg:
            if not (0.0 <= a <= 360.0 and 0.0 <= b <= 360.0) or a == b:
                raise ValueError(f"windows_deg: [{a:g}, {b:g}] is not a shaft-angle window;"
                                 " each window is [from, to] with both ends in 0 .. 360 deg and"
                                 " from != to ([350, 20] wraps through 0; [0, 360] is the whole"
                                 " cycle)")
        return self


class SpringSpec(_Spec):
    """``[[springs]]``: a translational spring-damper between two points, each on a link or
    on the frame (``links``, ``points``: the two ends). Its tension (N, positive when it
    pulls the ends together) is ``stiffness_N_per_mm`` times its stretch past
    ``free_length_mm``, or ``preload_N`` plus that stiffness times its length past
    ``length_mm``, plus ``damping_N_s_per_mm`` times the rate of its length."""

    name: str = Field(min_length=1, max_length=200)
    links: tuple[Name, Name]
    points: tuple[Name, Name]
    stiffness_N_per_mm: NonNegFloat = 0.0
    free_length_mm: NonNegFloat | None = None
    preload_N: Float | None = None
    length_mm: PosFloat | None = None
    damping_N_s_per_mm: NonNegFloat = 0.0
    note: str = ""

    @model_validator(mode="after")
    def _length(self):
        free, pre = self.free_length_mm is not None, (self.preload_N, self.length_mm)
        if free and any(x is not None for x in pre):
            raise ValueHint("give either free_length_mm, or preload_N with length_mm (the"
                            " length at which the spring pulls with preload_N), not both",
                            "Keep one of the two")
        if not free and (pre[0] is None) != (pre[1] is None):
            raise ValueHint("preload_N needs length_mm, the length at which the spring pulls"
                            " with it", "Give both, or free_length_mm instead")
        if not free and pre[0] is None and self.stiffness_N_per_mm > 0.0:
            raise ValueHint("a spring with stiffness needs free_length_mm, or preload_N with"
                            " length_mm", "Give e.g. free_length_mm = 20.0")
        if self.stiffness_N_per_mm == 0.0 and self.damping_N_s_per_mm == 0.0 and (
                self.preload_N in (None, 0.0)):
            raise ValueHint("the spring has no stiffness, no damping and no preload: it does"
                            " nothing", "Give stiffness_N_per_mm, damping_N_s_per_mm or"
                            " preload_N, or leave the spring out")
        return self

    @property
    def free_length(self) -> float:
        """Free length, mm (from the preload where that is given)."""
        if self.free_length_mm is not None:
            return self.free_length_mm
        if self.stiffness_N_per_mm == 0.0:
            return 0.0
        return self.length_mm - (self.preload_N or 0.0) / self.stiffness_N_per_mm


class TorsionSpringSpec(_Spec):
    """``[[torsion_springs]]``: a torsional spring-damper at a revolute pair (``pair``, as
    ``sewmech check --pairs`` names it). Its moment on the pair's second link (N mm,
    restoring) is ``stiffness_N_mm_per_deg`` times the pair's relative angle (second link's
    angle less the first's) past ``free_angle_deg``, or ``preload_N_mm`` plus that stiffness
    times the angle past ``angle_deg``, plus ``damping_N_mm_s_per_deg`` times its rate (deg/s);
    the first link takes the opposite moment."""

    name: str = Field(min_length=1, max_length=200)
    pair: str = Field(min_length=1, max_length=200)
    stiffness_N_mm_per_deg: NonNegFloat = 0.0
    free_angle_deg: Float | None = None
    preload_N_mm: Float | None = None
    angle_deg: Float | None = None
    damping_N_mm_s_per_deg: NonNegFloat = 0.0
    note: str = ""

    @model_validator(mode="after")
    def _angle(self):
        free, pre = self.free_angle_deg is not None, (self.preload_N_mm, self.angle_deg)
        if free and any(x is not None for x in pre):
            raise ValueHint("give either free_angle_deg, or preload_N_mm with angle_deg, not"
                            " both", "Keep one of the two")
        if not free and (pre[0] is None) != (pre[1] is None):
            raise ValueHint("preload_N_mm needs angle_deg, the relative angle at which the"
                            " spring holds it", "Give both, or free_angle_deg instead")
        if not free and pre[0] is None:
            raise ValueHint("a torsion spring needs free_angle_deg, or preload_N_mm with"
                            " angle_deg", "Give e.g. free_angle_deg = 0.0")
        if self.stiffness_N_mm_per_deg == 0.0 and self.damping_N_mm_s_per_deg == 0.0 and (
                self.preload_N_mm in (None, 0.0)):
            raise ValueHint("the torsion spring has no stiffness, no damping and no preload: it"
                            " does nothing", "Give stiffness_N_mm_per_deg,"
                            " damping_N_mm_s_per_deg or preload_N_mm, or leave it out")
        return self

    @property
    def free_angle(self) -> float:
        """Relative angle at which the spring holds no moment, deg."""
        if self.free_angle_deg is not None:
            return self.free_angle_deg
        if self.stiffness_N_mm_per_deg == 0.0:
            return self.angle_deg
        return self.angle_deg - self.preload_N_mm / self.stiffness_N_mm_per_deg


#: the largest friction coefficient sewmech takes: dry steel on steel is about 0.8, and a
#: coefficient of 1 or more in a pin would lock most linkages
MAX_FRICTION = 1.0


class PairFriction(_Spec):
    """Friction of one pair (``[friction.pairs]``): any of the defaults overridden."""

    coefficient: NonNegFloat | None = Field(None, le=MAX_FRICTION)
    pin_radius_mm: NonNegFloat | None = Field(None, le=1000.0)
    viscous_N_mm_s: NonNegFloat | None = None


class FrictionSpec(_Spec):
    """``[friction]``: Coulomb friction in every pair (docs/dynamics.md). ``coefficient`` mu;
    revolute pairs: the friction moment mu r |F| about the pin (``pin_radius_mm`` r, the pin's
    radius); prismatic pairs: mu |N| along the guide; cam and slot contacts: mu N along the
    contact's tangent; each against the relative motion, with a smooth sign below
    ``smooth_mm_s`` of sliding speed (revolute pairs: that speed at the pin's radius).
    ``viscous_N_mm_s``: a viscous part, that many N mm (N for sliding pairs) per unit of
    relative speed (rad/s; mm/s). ``pairs``: a table per pair name overriding any of
    these."""

    coefficient: NonNegFloat = Field(0.0, le=MAX_FRICTION)
    pin_radius_mm: NonNegFloat = Field(0.0, le=1000.0)
    viscous_N_mm_s: NonNegFloat = 0.0
    smooth_mm_s: PosFloat = 1.0
    pairs: dict[str, PairFriction] = Field(default_factory=dict)
    note: str = ""


Vec3Pos = tuple[PosFloat, PosFloat, PosFloat]


class MountSpec(_Spec):
    """One mount of the housing (``[[housing.mounts]]``): where it holds the housing (machine
    frame, mm), its stiffness along x, y, z (N/mm) and its damping along them (N s/mm; default:
    the housing's ``loss_factor``)."""

    name: str = Field(min_length=1, max_length=200)
    at_mm: Vec3
    stiffness_N_per_mm: tuple[NonNegFloat, NonNegFloat, NonNegFloat]
    damping_N_s_per_mm: tuple[NonNegFloat, NonNegFloat, NonNegFloat] | None = None
    note: str = ""


class HousingSpec(_Spec):
    """``[housing]``: the machine's housing (head, arm and bed) as a rigid body on elastic
    mounts, excited by every force the mechanisms put on it (docs/vibration.md).

    ``mass``: its mass properties in the machine frame (a ``[masses]``-style table without
    ``origin``: measured ``mass``, ``com`` [x, y, z] and a full ``inertia`` tensor, or solids);
    ``mounts``: at least one; ``loss_factor``: the mounts' structural damping where a mount
    gives no damping; ``control_points``: name -> [x, y, z] mm, where the vibration is judged
    (the operator's hands); ``bounds_mm``: the housing's extent [[x0, x1], [y0, y1], [z0, z1]],
    inside which mounts and control points must lie; ``planes_mm``: the z of the plane in which
    each frame pair (or a spring anchored to the frame) acts, by name, and ``default_plane_mm``
    for the others (the upper shaft's cranks act through its bearings, at ``[shaft]``'s z)."""

    mass: MassSpec
    mounts: list[MountSpec] = Field(min_length=1)
    loss_factor: NonNegFloat = Field(0.1, le=2.0)
    control_points: dict[Name, Vec3] = Field(min_length=1)
    bounds_mm: tuple[tuple[Float, Float], tuple[Float, Float], tuple[Float, Float]] | None = None
    planes_mm: dict[str, Float] = Field(default_factory=dict)
    default_plane_mm: Float = 0.0
    note: str = ""

    @model_validator(mode="after")
    def _housing(self):
        if self.mass.origin is not None:
            raise ValueHint("the housing's mass properties are in the machine frame: it has no"
                            " origin point", "Leave out origin")
        if self.mass.mass is not None and self.mass.inertia is None:
            raise ValueHint("the housing turns in 3-D on its mounts: give its full inertia"
                            " tensor (inertia = [[Ixx, Ixy, Ixz], ...], kg mm^2 about its centre"
                            " of mass), not only inertia_zz", "Give inertia, or solids")
        if self.mass.mass is not None and len(self.mass.com) != 3:
            raise ValueHint("the housing's com needs x, y and z (mm)", "Write com = [x, y, z]")
        names = [m.name for m in self.mounts]
        if len(set(names)) != len(names):
            raise ValueHint("two mounts share a name", "Give every mount its own name")
        if self.bounds_mm is not None:
            for lo, hi in self.bounds_mm:
                if not lo < hi:
                    raise ValueHint(f"bounds_mm: [{lo:g}, {hi:g}] is not a range (low < high)",
                                    "Write [[x0, x1], [y0, y1], [z0, z1]] with x0 < x1, ...")
        return self


class LoadFile(_Spec):
    """A load file: ``[[loads]]`` tables that replace the machine file's loads."""

    loads: list[LoadSpec] = Field(default_factory=list)


class ShaftSpec(_Spec):
    """``[shaft]``: the upper shaft in 3-D for its bearing reactions.

    ``links``: the crank links that turn with the shaft and the axial position z (mm) of the
    plane in which each one's pins and contacts act; ``bearings``: z of the front and rear
    bearings' mid-planes. z is the third axis of the machine frame (x, y, z right-handed), the
    axis that link mass properties also use.
    """

    links: dict[Name, Float] = Field(min_length=1)
    bearings: dict[Literal["front", "rear"], Float]
    note: str = ""

    @model_validator(mode="after")
    def _two(self):
        if set(self.bearings) != {"front", "rear"}:
            raise ValueError("bearings needs both 'front' and 'rear' (z of each, mm)")
        if self.bearings["front"] == self.bearings["rear"]:
            raise ValueError("the front and rear bearings must be at different z")
        return self


#: the keys of each kind of motor (besides kind, the belt, the inertias and the note)
MOTOR_KEYS = {
    "table": ("speed_rpm", "torque_N_mm"),
    "induction": ("synchronous_rpm", "rated_rpm", "rated_power_W", "breakdown_torque_ratio"),
    "clutch": ("synchronous_rpm", "rated_rpm", "rated_power_W", "breakdown_torque_ratio",
               "clutch_torque_N_mm", "brake_torque_N_mm"),
    "servo": ("max_torque_N_mm", "bandwidth_hz"),
}
#: the keys a kind may leave out (the run takes 0 N mm of brake and a 10 Hz speed loop)
_MOTOR_OPTIONAL = {"brake_torque_N_mm", "bandwidth_hz"}


def _a(word: str) -> str:
    """``word`` with its indefinite article."""
    return ("an " if word[:1] in "aeiou" else "a ") + word


class MotorSpec(_Spec):
    """``[motor]``: the motor that drives the upper shaft, for the run in time
    (docs/running.md). ``kind``: ``table`` (the torque at the motor's shaft against its speed,
    ``speed_rpm`` from 0 increasing and ``torque_N_mm``), ``induction`` (Kloss's curve through
    the rated point, ``rated_rpm`` and ``rated_power_W``, with the breakdown torque
    ``breakdown_torque_ratio`` times the rated one, ``synchronous_rpm``), ``clutch`` (that
    induction motor running before a dry clutch that passes at most ``clutch_torque_N_mm``; a
    brake of ``brake_torque_N_mm`` stops the machine) or ``servo`` (a speed controller, PI with
    the torque limit ``max_torque_N_mm`` and the speed loop's ``bandwidth_hz``). The motor
    turns ``belt_ratio`` times as fast as the shaft; ``rotor_inertia_kg_mm2`` is its own turning
    parts' (a clutch motor's rotor with its flywheel), ``hand_wheel_inertia_kg_mm2`` what turns
    with the shaft and is not in ``[masses]``. Torques N mm at the motor's shaft."""

    kind: str
    belt_ratio: Annotated[Float, Field(gt=0.0, le=100.0)] = 1.0
    rotor_inertia_kg_mm2: NonNegFloat = 0.0
    hand_wheel_inertia_kg_mm2: NonNegFloat = 0.0
    speed_rpm: list[Annotated[Float, Field(ge=0.0, le=1e5)]] | None = None
    torque_N_mm: list[Float] | None = None
    synchronous_rpm: Annotated[Float, Field(gt=0.0, le=1e5)] | None = None
    rated_rpm: Annotated[Float, Field(gt=0.0, le=1e5)] | None = None
    rated_power_W: Annotated[Float, Field(gt=0.0, le=1e6)] | None = None
    breakdown_torque_ratio: Annotated[Float, Field(gt=1.0, le=20.0)] | None = None
    clutch_torque_N_mm: PosFloat | None = None
    brake_torque_N_mm: NonNegFloat | None = None
    max_torque_N_mm: PosFloat | None = None
    bandwidth_hz: Annotated[Float, Field(gt=0.0, le=1000.0)] | None = None
    note: str = ""

    @field_validator("kind", mode="before")
    @classmethod
    def _kind(cls, v):
        if isinstance(v, str) and v in MOTOR_KEYS:
            return v
        import difflib

        close = difflib.get_close_matches(str(v), list(MOTOR_KEYS), n=1, cutoff=0.6)
        raise ValueHint(f"unknown motor kind; expected one of: {', '.join(MOTOR_KEYS)}",
                        f"Did you mean kind = \"{close[0]}\"?" if close else
                        "Write e.g. kind = \"induction\" (docs/running.md)")

    @model_validator(mode="after")
    def _keys_of_its_kind(self):
        own = MOTOR_KEYS[self.kind]
        others = [k for keys in MOTOR_KEYS.values() for k in keys if k not in own]
        stray = [k for k in dict.fromkeys(others) if getattr(self, k) is not None]
        if stray:
            kinds = [k for k, keys in MOTOR_KEYS.items() if stray[0] in keys]
            raise ValueHint(f"{stray[0]} is for {_a(' or '.join(kinds))} motor; this one is"
                            f" {_a(self.kind)} motor", f"Leave {stray[0]} out, or write kind ="
                            f" \"{kinds[0]}\"")
        missing = [k for k in own if getattr(self, k) is None and k not in _MOTOR_OPTIONAL]
        if missing:
            needed = [k for k in own if k not in _MOTOR_OPTIONAL]
            raise ValueHint(f"{_a(self.kind)} motor needs {', '.join(needed)}; missing:"
                            f" {', '.join(missing)}", "Add them (docs/running.md)")
        if self.kind == "table":
            n, t = self.speed_rpm, self.torque_N_mm
            if len(n) != len(t) or len(n) < 2:
                raise ValueHint(f"speed_rpm and torque_N_mm must be lists of the same length,"
                                f" at least 2 (got {len(n)} and {len(t)})",
                                "Give the torque at each speed")
            if n[0] != 0.0 or any(b <= a for a, b in zip(n[:-1], n[1:], strict=True)):
                raise ValueHint(f"speed_rpm must start at 0 and increase, got {_short(n)}",
                                "Give the torque from standstill (0 rpm) up")
        if self.kind in ("induction", "clutch") and not (
                self.rated_rpm < self.synchronous_rpm):
            raise ValueHint(f"rated_rpm = {self.rated_rpm:g} must be below synchronous_rpm ="
                            f" {self.synchronous_rpm:g}: an induction motor's torque comes from"
                            " its slip", "Give the rated speed from the motor's plate (e.g."
                            " 2800 for a 2-pole motor on 50 Hz, synchronous 3000)")
        return self


class MachineSpec(_Spec):
    """The whole machine file."""

    machine: MachineInfo
    convention: Convention
    speed: Speed = Speed()
    points: dict[Name, PointSpec] = Field(min_length=1)
    inputs: dict[Name, InputSpec] = Field(default_factory=dict)
    cams: dict[Name, CamSpec] = Field(default_factory=dict)
    units: list[Unit] = Field(min_length=1)
    sewing: SewingSpec | None = None
    thread: ThreadSpec | None = None
    masses: dict[Name, MassSpec] = Field(default_factory=dict)
    loads: list[LoadSpec] = Field(default_factory=list)
    springs: list[SpringSpec] = Field(default_factory=list)
    torsion_springs: list[TorsionSpringSpec] = Field(default_factory=list)
    friction: FrictionSpec | None = None
    housing: HousingSpec | None = None
    shaft: ShaftSpec | None = None
    counterweights: dict[Name, CounterweightSpec] = Field(default_factory=dict)
    motor: MotorSpec | None = None

    @field_validator("points")
    @classmethod
    def _no_frame(cls, v):
        if FRAME in v:
            raise ValueError(f"'{FRAME}' is reserved for the frame link")
        return v


# ---- loading ------------------------------------------------------------------------------------


def _allowed_keys(model: type[BaseModel]) -> list[str]:
    return sorted(model.model_fields)


def _model_at(loc: tuple, raw, root: type[BaseModel] = MachineSpec
              ) -> tuple[type[BaseModel] | None, list[str], int, tuple]:
    """Walk MachineSpec along a pydantic error location.

    Returns the innermost model, the human-readable path (tables, list items with their
    ``name``, keys), how many of its parts lead to that model (its table) and the parts of
    ``loc`` left over below the last field (tuple indices, unknown keys).
    """
    model: type[BaseModel] | None = root
    path: list[str] = []
    n_model = 0
    node = raw
    i = 0
    ann = None
    while i < len(loc) and model is not None:
        part = loc[i]
        if part not in model.model_fields:
            break
        path.append(str(part))
        ann = model.model_fields[part].annotation
        node = node.get(part) if isinstance(node, dict) else None
        i += 1
        model = None
        # unwrap containers: dict[str, M], list[M], list[Union[...]], M | None
        while ann is not None:
            origin = typing.get_origin(ann)
            args = typing.get_args(ann)
            if origin is Annotated:
                ann = args[0]
                continue
            if origin in (dict, list) and i < len(loc):
                key = loc[i]
                if origin is list:
                    label = f"[{key}]"
                    if isinstance(node, list) and isinstance(key, int) and key < len(node):
                        node = node[key]
                        if isinstance(node, dict) and isinstance(node.get("name"), str):
                            label += f' "{node["name"]}"'
                    else:
                        node = None
                    path[-1] += label
                else:
                    path.append(str(key))
                    node = node.get(key) if isinstance(node, dict) else None
                i += 1
                ann = args[-1]
                continue
            if origin is Union or origin is typing.Union or origin is types.UnionType:
                members = [a for a in args if isinstance(a, type) and issubclass(a, BaseModel)]
                if i < len(loc) and any(
                    m.model_fields.get("type") is not None
                    and loc[i] in typing.get_args(m.model_fields["type"].annotation)
                    for m in members
                ):
                    for m in members:
                        if loc[i] in typing.get_args(m.model_fields["type"].annotation):
                            ann = m
                    i += 1
                    continue
                rest_args = [a for a in args if a is not type(None)]
                if len(members) == 1:
                    ann = members[0]
                elif not members and len(rest_args) == 1:  # X | None: X itself
                    ann = rest_args[0]
                else:
                    ann = None
                continue
            if isinstance(ann, type) and issubclass(ann, BaseModel):
                model = ann
                n_model = len(path)
            ann = None
    return model, path, n_model, tuple(loc[i:])


def _first(errors: list[dict]) -> dict:
    """The error to report: an unknown key before anything else (a misspelt key is also
    reported missing under its right name; the misspelling is what the user must see)."""
    return next((e for e in errors if e["type"] == "extra_forbidden"), errors[0])


def _short(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


#: what a counterweight's value out of its domain means, and what to give instead
_COUNTERWEIGHT_DOMAIN = {
    "static_moment_gcm": ("a counterweight's static moment cannot be negative",
                          "Give 0 (no counterweight) or more; turn it by angle_deg instead"),
    "mass_g": ("a counterweight's mass cannot be negative",
               "Give 0 (no counterweight) or more; move it by at_mm instead"),
    "radius_mm": ("the radius where the counterweight's centre of mass sits must be > 0 mm",
                  "Give its distance from the origin of the link's frame (a counterweight on"
                  " that point balances nothing)"),
    "max_static_moment_gcm": ("the largest static moment the space allows must be > 0 g cm",
                              "Give what fits there, or leave the key out for no limit"),
    "bore_mm": ("the diameter of the shaft the counterweight is clamped on must be > 0 mm",
                "Give the shaft's diameter at the counterweight, or leave the key out"),
}


def _counterweight_domain(key: str, got) -> tuple[str, str]:
    """(message, hint) of a counterweight value below its domain."""
    what, hint = _COUNTERWEIGHT_DOMAIN.get(key, ("must be a positive number", "Give one"))
    unit = {"gcm": " g cm", "g": " g", "mm": " mm"}.get(key.rpartition("_")[2], "")
    shown = f"{got:g}{unit}" if isinstance(got, int | float) else _short(got)
    return f"is {shown}: {what}", hint


#: pydantic's errors of a number beyond a bound: the comparison and the bound's key in ctx
_BOUND_ERRORS = {"greater_than": (">", "gt"), "greater_than_equal": (">=", "ge"),
                 "less_than": ("<", "lt"), "less_than_equal": ("<=", "le")}


def _explain(err: dict, raw: dict, file: str, root: type[BaseModel] = MachineSpec,
             doc: str = "docs/machine-files.md") -> MachineFileError:
    loc = tuple(err["loc"])
    model, path, n_model, rest = _model_at(loc, raw, root)
    etype = err["type"]
    if model is not None and n_model == len(path) and not rest:
        table, key = ".".join(path), ""  # the table as a whole (a model validator)
    else:
        # a top-level table of plain values (a tolerance file's [parameters]) is the table
        k = 1 if n_model == 0 and path and isinstance(raw.get(path[0]), dict) else n_model
        table = ".".join(path[:k])
        key = ".".join(path[k:])
        for part in rest:
            key += f"[{part}]" if isinstance(part, int) else (f".{part}" if key else str(part))
    got = err.get("input")
    hint = ""
    if etype == "extra_forbidden":
        keys = _allowed_keys(model) if model is not None else []
        import difflib

        close = difflib.get_close_matches(str(loc[-1]), keys, n=1, cutoff=0.6)
        msg = f"unknown key '{loc[-1]}'; expected one of: {', '.join(keys) or '?'}"
        hint = (f"Did you mean '{close[0]}'?" if close else "Fix the spelling or remove the key")
        hint += f" ({doc})"
    elif etype == "missing":
        msg = f"missing required key '{loc[-1]}'"
        if path and path[-1] == str(loc[-1]):  # the key is the last part: its table is above
            table, key = ".".join(path[:-1]), str(loc[-1])
        hint = f"Add it ({doc} lists every key)"
    elif etype == "finite_number":
        msg = f"must be a finite number, got {_short(got)}"
        hint = "nan and inf are not values sewmech can compute with; write the number"
    elif etype == "literal_error" and key == "branch":
        msg = f"branch must be +1 or -1 (the assembly branch of the unit), got {got!r}"
    elif etype == "literal_error" and key == "length_unit":
        msg = f"length_unit must be \"mm\", got {_short(got)}"
        hint = ("sewmech reads every length of a machine file in millimetres; convert the"
                " file's lengths to mm")
    elif etype in ("greater_than", "greater_than_equal") and table.startswith("counterweights."):
        msg, hint = _counterweight_domain(key, got)
    elif etype in ("greater_than", "greater_than_equal") and "length" in key:
        msg = f"must be a positive length in mm, got {_short(got)}"
    elif etype in _BOUND_ERRORS:  # a number beyond a bound of its key (Field(ge=...))
        op, ctx_key = _BOUND_ERRORS[etype]
        limit = (err.get("ctx") or {}).get(ctx_key)
        shown = f"{limit:g}" if isinstance(limit, int | float) else str(limit)
        msg = f"must be {op} {shown}, got {_short(got)}"
        hint = f"Check the value and its unit ({doc}; docs/errors.md gives every range)"
    elif etype == "union_tag_not_found":
        msg = "missing key 'type'"
        hint = "Every unit says its type: crank, point, rrr, rrp, rpr or loop"
    elif etype in ("float_type", "int_type", "bool_type") and isinstance(got, str):
        what = "flag" if etype == "bool_type" else "number"
        msg = f"must be a {what}, got the string {_short(got)}"
        hint = "Write it without quotes"
    elif etype in ("float_type", "int_type") and isinstance(got, bool):
        msg = f"must be a number, got {str(got).lower()}"
    elif etype == "bool_type":
        msg = f"must be true or false, got {_short(got)}"
    elif etype == "string_pattern_mismatch":
        msg = f"{_short(got)} is not a name"
        hint = ("Names are letters, digits and _ . - and start with a letter or _ (quote names"
                " with dots as TOML keys: \"needle.eye\")")
    elif etype == "union_tag_invalid":
        msg = (f"unknown unit type {got.get('type')!r}; expected one of: crank, point,"
               " rrr, rrp, rpr, loop") if isinstance(got, dict) else err["msg"]
    elif etype == "value_error":
        msg = err["msg"].removeprefix("Value error, ")
        if not isinstance(got, dict | list):
            msg += f" (got {_short(got)})"
        cause = (err.get("ctx") or {}).get("error")
        if isinstance(cause, ValueHint):
            hint = cause.hint
    elif etype in ("dict_type", "model_type", "model_attributes_type"):
        msg = f"must be a table ({{ key = value, ... }} or [{'.'.join(path)}]), got {_short(got)}"
    elif etype == "literal_error":  # one of a few words or numbers
        expected = str((err.get("ctx") or {}).get("expected", "")) or "one of its values"
        msg = f"must be {expected}, got {_short(got)}"
        hint = f"Give {'one of them' if ' or ' in expected else expected} ({doc})"
    elif etype == "string_type":
        msg = f"must be a string, got {_short(got)}"
        hint = "Write it in quotes, e.g. name = \"my-machine\""
    else:  # pydantic's wording, without its "Input should be"
        msg = f"{err['msg'].replace('Input should be', 'should be')} (got {_short(got)})"
        hint = f"See {doc} for what it takes"
    return MachineFileError(file, table, key, msg, hint)


#: the largest machine or load file sewmech reads, bytes (the shipped JB files are 44 kB)
MAX_FILE_BYTES = 4 * 1024 * 1024


def read_toml_text(path: str | Path, what: str = "machine file") -> str:
    """The text of a TOML file, or a :class:`MachineFileError` that says why it cannot be read:
    missing, a directory, too large, binary, not UTF-8."""
    path = user_path(path)
    file = str(path)
    try:
        why = not_regular(path)
        if why is not None:
            raise MachineFileError(file, "", "", f"{why}; a {what} is a TOML text file",
                                   "Give the path of a .toml file")
        size = path.stat().st_size
        if size > MAX_FILE_BYTES:
            raise MachineFileError(file, "", "", f"is {size / 2**20:.1f} MiB; a {what} is at"
                                   f" most {MAX_FILE_BYTES // 2**20} MiB of TOML text",
                                   f"Check that this is the {what} you meant")
        with path.open("rb") as fh:
            data = fh.read(MAX_FILE_BYTES + 1)
    except OSError as exc:
        raise MachineFileError(file, "", "", f"cannot read the file: {exc.strerror or exc}",
                               "Check the path and its permissions") from None
    return toml_text(data, file, what)


def toml_text(data: bytes, file: str, what: str = "machine file") -> str:
    """Bytes of a TOML file (read from disk or received, e.g. uploaded to ``sewmech serve``)
    as text, with the checks of :func:`read_toml_text`: at most :data:`MAX_FILE_BYTES`, not
    binary, UTF-8 (a byte-order mark is dropped)."""
    if len(data) > MAX_FILE_BYTES:
        raise MachineFileError(file, "", "", f"is more than {MAX_FILE_BYTES // 2**20} MiB; a"
                               f" {what} is at most {MAX_FILE_BYTES // 2**20} MiB of TOML text",
                               f"Check that this is the {what} you meant")
    if b"\0" in data:
        raise MachineFileError(file, "", "", f"is a binary file, not a {what} (TOML text)",
                               "Give the path of a .toml file")
    try:
        return data.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = data[:exc.start].count(b"\n") + 1
        raise MachineFileError(file, "", "", f"is not UTF-8 text (byte 0x{data[exc.start]:02x}"
                               f" on line {line})", "Save the file as UTF-8") from None


#: What any TOML file sewmech reads may hold (machine, load, problem, sweep and tolerance
#: files, and uploads to ``sewmech serve``), checked by :func:`check_toml_bounds` before the
#: text reaches Python's TOML parser (docs/machine-files.md). Each is far beyond the largest
#: shipped file (jb1-3.toml: 44 kB, lines of at most 357 characters, 1,696 keys, tables and
#: array items, table names of 2 parts, no dotted keys, arrays of 18 items) and together they
#: bound the parser's time: tomllib's time and memory grow with the parts of a dotted key times
#: the parts of its whole name (one 100 kB key of 50,000 parts took 51 s and 10 GB), it
#: recurses once a level of nesting, and it converts integers of any length. Within them, the
#: slowest text measured (3.8 MiB of escapes in strings) parses in about 2 s.
TOML_LIMITS = {
    "key_parts": 64,         # parts of one dotted key or table name (a.b.c: 3)
    "depth": 32,             # arrays and inline tables inside one another
    "array_items": 10_000,   # items of one array
    "items": 50_000,         # keys, tables (a dotted name once a part), array items: the file
    "line_chars": 100_000,   # characters of one line (all of jb1-3's units inline: 18,127)
    "string_chars": 100_000,  # characters of one string (a multi-line note: its lines too)
    "number_chars": 100,     # characters of one number (digits, sign, point, exponent, _)
}
#: TOML's integers: 64-bit signed (the TOML 1.0 specification refuses any other)
TOML_INT_RANGE = (-2**63, 2**63 - 1)

# The tokens of TOML text for :func:`check_toml_bounds`. Every pattern matches in time linear in
# its length and never backtracks (possessive repeats, alternatives that start differently); a
# character no token of valid TOML starts with ends the scan (the parser refuses the text there
# or before). Bare runs take dots in, so a dotted key or a float is one token.
_TOML_TOKEN = re.compile(r"""
    [ \t]*+(?:\#[^\n]*+)?         # blanks and a comment before each token
    (?:(?P<nl>\r?\n)
     | (?P<mlstr>\"\"\"(?:[^"\\]++|\\[\s\S]|"{1,2}+(?!"))*+"{3,5}
               |'''(?:[^']++|'{1,2}+(?!'))*+'{3,5})
     | (?P<str>"(?:[^"\\\n]++|\\[^\n])*+"|'[^'\n]*+')
     | (?P<bare>[A-Za-z0-9_+\-:.]++)
     | (?P<punct>[\[\]{},=])
     | (?P<other>[\s\S])
     | \Z)
""", re.VERBOSE)
_TOML_INT = re.compile(r"[+-]?(?:0x[0-9A-Fa-f_]+|0o[0-7_]+|0b[01_]+|[0-9][0-9_]*)")


def check_toml_bounds(text: str, file: str) -> dict[str, int]:
    """Refuse TOML text beyond :data:`TOML_LIMITS`, or with an integer outside TOML's 64-bit
    range, before it is parsed: a :class:`MachineFileError` naming the file and the line. One
    pass over the tokens, in time linear in the text, that stops at the first excess.

    Returns the text's shape: ``items`` (keys, tables and array items, a dotted name counted
    once a part), ``dotted_keys`` (keys of more than one part), ``dotted_key_parts`` and
    ``table_parts`` (the most parts of a key and of a table's name)."""
    lim = TOML_LIMITS
    max_parts, max_depth, max_items = lim["key_parts"], lim["depth"], lim["items"]
    max_array, max_line = lim["array_items"], lim["line_chars"]
    line, line_start = 1, 0
    stack: list[list] = []      # open arrays ["a", items] and inline tables ["t", 0]
    key_mode = True             # reading a key (or a table's name) rather than a value
    value_next = False          # the next token starts a value
    parts = 0                   # parts of the key being read (0: none yet)
    items = 0                   # keys, tables and array items so far
    dotted, most_key, most_table = 0, 1, 0

    def refuse(what: str, hint: str) -> typing.NoReturn:
        err = MachineFileError(f"{file}, line {line}", "", "", what, hint)
        err.file = file  # where names the line; file stays the file
        raise err

    too_many = (f"holds more than {max_items:,} keys, tables and array items (a dotted name"
                " counts once a part)", "A file sewmech reads is far smaller; check that this"
                " is the file you meant")
    too_long = (f"holds an array of more than {max_array:,} items", "A file sewmech reads has"
                " far shorter arrays; check that this is the file you meant")
    for m in _TOML_TOKEN.finditer(text):
        kind = m.lastgroup
        if kind is None:
            continue  # the end of the text (after blanks or a comment)
        tok = m.group(kind)
        if kind == "nl":
            n = m.start(kind) - line_start
            if n > max_line:
                refuse(f"is {n:,} characters long; a line is at most {max_line:,}",
                       "Break it (arrays may span lines)")
            line, line_start = line + 1, m.end()
            if not stack:
                key_mode, value_next, parts = True, False, 0
            continue
        if kind == "other":
            break  # not TOML from here on: the parser says where
        if kind == "mlstr" or kind == "str":
            n = len(tok) - (6 if kind == "mlstr" else 2)  # without its quotes
            if n > lim["string_chars"]:
                refuse(f"holds a string of {n:,} characters; a string is at most"
                       f" {lim['string_chars']:,}", "Shorten it")
            if kind == "mlstr" and "\n" in tok:  # its lines: no longer than it is
                line += tok.count("\n")
                line_start = m.start(kind) + tok.rindex("\n") + 1
        if key_mode:  # a key (a = ...), a table's name ([a.b], [[a]]), or their end
            if kind == "punct":
                if tok == "=":
                    items += parts or 1  # a key counts once a part: the parser's work
                    if parts > 1:
                        dotted, most_key = dotted + 1, max(most_key, parts)
                    key_mode, value_next, parts = False, True, 0
                elif tok == "]" and not stack:
                    items += parts or 1  # a table's name, likewise
                    most_table = max(most_table, parts)
                    key_mode, parts = False, 0
                elif tok == "}" and stack and stack[-1][0] == "t":
                    stack.pop()  # an empty inline table
                    key_mode = False
                if items > max_items:
                    refuse(*too_many)
                continue
            parts = (parts or 1) + (tok.count(".") if kind == "bare" else 0)
            if parts > max_parts:
                refuse(f"holds a dotted key or table name of more than {max_parts} parts",
                       "Write the key with fewer dots (a name with dots is quoted:"
                       " \"needle.eye\")")
            continue
        # a value, or what separates values
        if kind == "punct":
            if tok == "[" or tok == "{":
                if value_next and stack and stack[-1][0] == "a":
                    stack[-1][1] += 1
                    items += 1
                    if stack[-1][1] > max_array:
                        refuse(*too_long)
                stack.append(["a" if tok == "[" else "t", 0])
                if len(stack) > max_depth:
                    refuse(f"nests arrays or tables too deeply (more than {max_depth}"
                           " levels)", "Check the file's brackets")
                key_mode, parts, value_next = tok == "{", 0, tok == "["
            elif tok == "]" or tok == "}":
                if stack:
                    stack.pop()
                value_next = False
            elif tok == ",":
                in_table = bool(stack) and stack[-1][0] == "t"
                key_mode, parts, value_next = in_table, 0, bool(stack) and not in_table
        elif value_next:  # a value starts: a string, a number, a date, a flag
            value_next = False
            if stack and stack[-1][0] == "a":
                stack[-1][1] += 1
                items += 1
            if kind == "bare" and _TOML_INT.fullmatch(tok):
                digits = tok.lstrip("+-").replace("_", "")
                try:  # at most 66 characters converted (a 64-bit integer in binary)
                    value = (None if len(digits) > 66 else int(digits, 0)
                             if digits[1:2] in ("x", "o", "b") else int(digits))
                except ValueError:
                    value = 0  # not an integer TOML has ("0x_"): the parser says so
                if value is None or not TOML_INT_RANGE[0] <= (
                        -value if tok[0] == "-" else value) <= TOML_INT_RANGE[1]:
                    n = len(digits) - (2 if digits[1:2] in ("x", "o", "b") else 0)
                    refuse(f"holds the integer {_short(tok, 30)} ({n:,} digits),"
                           f" beyond the 64-bit integers TOML allows ({TOML_INT_RANGE[0]} .."
                           f" {TOML_INT_RANGE[1]})", "Write the number sewmech should use")
            elif kind == "bare" and len(tok) > lim["number_chars"]:
                refuse(f"holds a value of {len(tok):,} characters; a number is at most"
                       f" {lim['number_chars']}", "Write the number with fewer digits")
        else:
            continue  # the rest of a value (a date's time), or text the parser refuses
        if stack and stack[-1][1] > max_array:
            refuse(*too_long)
        if items > max_items:
            refuse(*too_many)
    else:
        if len(text) - line_start > max_line:
            refuse(f"is {len(text) - line_start:,} characters long; a line is at most"
                   f" {max_line:,}", "Break it (arrays may span lines)")
    return {"items": items, "dotted_keys": dotted, "dotted_key_parts": most_key,
            "table_parts": most_table}


def _parse_toml(text: str, file: str) -> dict:
    """TOML text as data: its bounds checked first (:func:`check_toml_bounds`), then parsed;
    every problem a :class:`MachineFileError` naming the file (and the line, where known)."""
    check_toml_bounds(text, file)
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as exc:
        raise MachineFileError(file, "", "", f"not valid TOML: {exc}",
                               "Fix the syntax at that line (https://toml.io)") from None
    except RecursionError:
        raise MachineFileError(file, "", "", "nests arrays or tables too deeply to be a machine"
                               " file", "Check the file's brackets") from None
    except ValueError as exc:  # a number the parser cannot convert (bounds missed it)
        raise MachineFileError(file, "", "", f"not valid TOML: {exc}",
                               "Write the numbers as TOML does (https://toml.io)") from None


def validate_model(model: type[BaseModel], raw: dict, file: str,
                   doc: str = "docs/machine-files.md"):
    """``model`` validated from TOML data, or the :class:`MachineFileError` of its first
    problem (file, table, key; ``doc`` is where the format is described)."""
    try:
        return model.model_validate(raw)
    except ValidationError as exc:
        raise _explain(_first(exc.errors()), raw, file, model, doc) from None
    except RecursionError:
        raise MachineFileError(file, "", "", "nests arrays or tables too deeply to be a machine"
                               " file", "Check the file's brackets") from None


def parse_machine(text: str, file: str = "<string>") -> MachineSpec:
    """Parse machine-file TOML text into a validated :class:`MachineSpec`.

    Raises
    ------
    MachineFileError
        With file, table and key of the first problem found.
    """
    return validate_model(MachineSpec, _parse_toml(text, file), file)


def load_machine_spec(path: str | Path) -> MachineSpec:
    """Read and validate a machine file (TOML)."""
    return parse_machine(read_toml_text(path), str(path))


def load_toml_model(path: str | Path, model: type[BaseModel], what: str,
                    doc: str = "docs/machine-files.md"):
    """A TOML file read (its size, encoding and nesting checked) and validated as ``model``;
    every problem a :class:`MachineFileError` naming the file, the table and the key. For the
    files a user edits besides machine files: loads, tolerances, design problems."""
    path = user_path(path)
    return validate_model(model, _parse_toml(read_toml_text(path, what), str(path)), str(path),
                          doc)


def load_load_file(path: str | Path) -> list[LoadSpec]:
    """Read and validate a load file (``[[loads]]`` tables, as in machine files)."""
    loads = list(load_toml_model(path, LoadFile, "load file").loads)
    if not loads:
        raise MachineFileError(str(path), "", "", "holds no [[loads]] tables", "A load file"
                               " replaces the machine file's loads; for a run without process"
                               " loads use --no-loads (or loads=[])")
    return loads
