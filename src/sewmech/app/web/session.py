"""What the interactive page computes, and nothing of the web: one :class:`Session` per page.

A session holds one compiled machine (a shipped file or an uploaded text) and the calls
prepared for it; every request brings the page's whole set of changed values (``{name: value}``
in the units the parameter table lists: mm, deg, g, g cm), so a request never depends on an
earlier one and two pages never share anything. The numbers come from the library's own calls
(:class:`~sewmech.engine.dynamics.DynamicsPlan` for the turn and its forces,
:func:`~sewmech.sewing.feed.feed_cycles`, :func:`~sewmech.sewing.thread.thread_balance`,
:func:`~sewmech.sewing.checks.check_timing`); this module only chooses them and hands their
arrays to :mod:`.encode`, which writes them as JSON lists rounded to 1e-6 (a value that could
not be computed is ``None``, never NaN).

Units in the answers: mm, s, N, N mm; angles in degrees only where a key ends in ``_deg``.
"""

from __future__ import annotations

import math
import threading
from dataclasses import dataclass, field

import numpy as np

from ...engine.errors import MachineFileError, ParameterError, SewmechError
from ...engine.machine import FILE_UNITS, MIN_LENGTH, PARAM_LIMIT, Machine, machine_from_toml
from .encode import DECIMALS, Arr, dumps, plain

#: the shaft-angle step of the drawn turn, deg (180 positions: smooth at screen size, and the
#: whole turn with its forces in a few milliseconds)
DRAW_STEP_DEG = 2.0
#: the step of the feed-dog cycle the stitch length is read from, deg (feed_cycles' and
#: `sewmech feed`'s own)
FEED_STEP_DEG = 1.0

#: the largest file the export edits in place, keeping its comments and layout (tomlkit):
#: that editor's time grows with the square of a file's dotted keys and the parts of its names
#: (measured: 64 keys of 64 parts 26 s, 2,000 points written `points.X.x = ...` 39 s, 128 keys
#: of 4 parts in one table 2 s; within these limits at most about 1 s), so a file beyond any
#: of them (its shape as :func:`~sewmech.engine.spec.check_toml_bounds` gives it) is written
#: anew from its values. The shipped files: at most 1,696 items, no dotted keys, table names
#: of 2 parts
EXPORT_IN_PLACE = {"items": 10_000, "dotted_keys": 64, "dotted_key_parts": 3,
                   "table_parts": 8}

#: keys of a unit's table that are design dimensions a designer turns first
_MAIN_KEYS = ("length", "lengths", "radius", "offset", "phase_deg", "guide_angle_deg",
              "eccentricity")
_CAM_KEYS = {"width": "mm", "stroke": "mm", "dwell": "rad", "orientation": "rad"}


class PageError(SewmechError):
    """A request the page cannot answer (an unknown machine, a malformed request)."""


def _shown(value, limit: int = 60) -> str:
    """A value from a request as a message shows it: its repr, cut to ``limit`` characters."""
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _num(x) -> float | None:
    x = float(x)
    return round(x, DECIMALS) if math.isfinite(x) else None


@dataclass
class Param:
    """One slider: a parameter (or a cam's design value) in the units people use."""

    name: str
    unit: str          # as shown: mm, deg, g, g cm, or "" (a ratio)
    factor: float      # shown = internal * factor
    value: float       # the file's value, shown units
    lo: float | None   # the domain, shown units (None: unbounded)
    hi: float | None
    slider_lo: float
    slider_hi: float
    step: float
    main: bool
    table: str         # where it sits in the file
    kind: str          # "input", "dimension", "cam", "counterweight"

    def to_dict(self) -> dict:
        return {k: getattr(self, k) for k in ("name", "unit", "value", "lo", "hi", "slider_lo",
                                              "slider_hi", "step", "main", "table", "kind")}


def _tidy(x: float) -> float:
    """A value converted to degrees (or g) without the last bits of the conversion."""
    return float(f"{x:.12g}")


def _slider(value: float, unit: str, lo: float | None, hi: float | None) -> tuple:
    """(slider_lo, slider_hi, step) around a value: +-30 % (at least 5 mm, 30 deg, ...)."""
    span = {"deg": 30.0, "mm": 5.0, "g": 50.0, "g cm": 100.0}.get(unit, 0.5)
    half = max(0.3 * abs(value), span)
    a, b = value - half, value + half
    if lo is not None:
        a = max(a, lo)
    if hi is not None:
        b = min(b, hi)
    step = {"deg": 0.1, "mm": 0.01, "g": 1.0, "g cm": 1.0}.get(unit, 0.001)
    return a, b, step


def parameter_table(machine: Machine) -> list[Param]:
    """Every parameter a designer can set (the arcs of a constant-width cam through its design
    values), the setting inputs first, then the main dimensions, then the rest."""
    out: list[Param] = []
    cw_names = {n for c in machine.counterweights for n in getattr(c, "parameter_names", ())}
    for i, name in enumerate(machine.parameter_names):
        src = machine.parameter_sources[i] if machine.parameter_sources else None
        if src is None:
            continue  # an arc of a constant-width cam: set through the cam's design values
        unit = machine.parameter_units[i]
        shown, factor = FILE_UNITS.get(unit, (unit, 1.0))
        shown = "" if shown == "1" else shown
        lo_i, hi_i = float(machine.parameter_lo[i]), float(machine.parameter_hi[i])
        lo = None if lo_i <= -PARAM_LIMIT else (0.0 if lo_i == MIN_LENGTH else lo_i * factor)
        hi = None if hi_i >= PARAM_LIMIT else hi_i * factor
        value = float(machine.defaults[i]) * factor
        if name.startswith("input."):
            kind, main = "input", True
        elif src[0] == "counterweights" or name in cw_names:
            kind, main = "counterweight", True
        else:
            kind = "dimension"
            main = src[0] == "units" and len(src) in (3, 4) and src[2] in _MAIN_KEYS
        lo, hi, value = (None if x is None else _tidy(x) for x in (lo, hi, value))
        a, b, step = _slider(value, shown, lo, hi)
        loc = machine.parameter_location(name)
        out.append(Param(name, shown, factor, value, lo, hi, a, b, step, main,
                         loc[0] if loc else "", kind))
    for cam, design in machine.cam_designs.items():
        for key, unit in _CAM_KEYS.items():
            shown, factor = FILE_UNITS.get(unit, (unit, 1.0))
            value = _tidy(float(design[key]) * factor)
            lo = 0.0 if unit == "mm" else None
            a, b, step = _slider(value, shown, lo, None)
            out.append(Param(f"{cam}.{key}", shown, factor, value, lo, None, a, b, step, True,
                             f"cams.{cam}.constant_width", "cam"))
    rank = {"input": 0, "cam": 1, "counterweight": 2, "dimension": 1}
    out.sort(key=lambda p: (not p.main, rank[p.kind]))
    return out


def shipped_texts() -> dict[str, tuple[str, str]]:
    """The shipped machines: name -> (file name, text). Read here once, by their names: a name
    from a request is looked up in this table and never becomes a path."""
    from ...engine.machine import shipped_machines
    from ...engine.spec import read_toml_text

    return {name: (path.name, read_toml_text(path)) for name, path in
            sorted(shipped_machines().items())}


@dataclass
class Session:
    """One page's machine and its prepared calls (guarded by one lock: the plans reuse their
    arrays, and the machine keeps caches)."""

    machine: Machine
    text: str
    file_name: str
    params: dict[str, Param] = field(init=False)
    lock: threading.Lock = field(default_factory=threading.Lock, init=False)
    #: the checks run on a second compiled copy of the machine under a lock of their own, so
    #: that a checks request (tens of ms) never holds up the next turn
    checks_lock: threading.Lock = field(default_factory=threading.Lock, init=False)
    _in_place: bool | None = field(default=None, init=False, repr=False)

    def __post_init__(self):
        from ...engine.dynamics import DynamicsPlan
        from ...engine.kinematics import KinematicsPlan

        m = self.machine
        self.table = parameter_table(m)
        self.params = {p.name: p for p in self.table}
        self.phi = np.radians(np.arange(0.0, 360.0, DRAW_STEP_DEG))
        self.dynamics_note = ""
        self._dyn = None
        if m.spec.masses:
            try:
                self._dyn = DynamicsPlan(m, self.phi)
            except SewmechError as exc:  # e.g. a force system the pairs do not determine
                self.dynamics_note = str(exc)
        else:
            self.dynamics_note = "the machine file has no [masses]: no forces"
        self._kin = None if self._dyn is not None else KinematicsPlan(m, self.phi)
        self._housing = None  # the housing on its mounts: its control points' levels live
        if self._dyn is not None and m.spec.housing is not None:
            from ...engine.housing import Housing

            try:
                self._housing = Housing.of(m)
            except SewmechError as exc:
                self.dynamics_note = str(exc)
        self._checks_machine = machine_from_toml(self.text, self.file_name)

    @property
    def in_place(self) -> bool:
        """Whether the export edits the file's text in place (tomlkit): only a file within
        :data:`EXPORT_IN_PLACE` (measured once)."""
        if self._in_place is None:
            from ...engine.spec import check_toml_bounds

            shape = check_toml_bounds(self.text, self.file_name)
            self._in_place = all(shape[k] <= v for k, v in EXPORT_IN_PLACE.items())
        return self._in_place

    def warm(self) -> None:
        """Build the calls' plans now (the first turn and checks of a machine take a few hundred
        ms), so that the page's first slider move is as fast as the next ones. A default
        design that fails is not an error here: the page's first turn reports it."""
        for fn in (self.turn, self.checks):
            try:
                fn({})
            except (SewmechError, ValueError):
                pass

    @classmethod
    def from_text(cls, text: str, file_name: str) -> Session:
        """A session of machine-file text, validated as every machine file is."""
        return cls(machine_from_toml(text, file_name), text, file_name)

    # ---- what the page shows once per machine -------------------------------------------------
    def info(self) -> dict:
        m = self.machine
        s = m.spec.sewing
        links: dict[str, list[str]] = {}
        for pt, owners in m.point_links.items():
            for link in owners:
                links.setdefault(link, []).append(pt)
        frame = sorted(set(links.pop("frame", [])))
        sliders = [{"pair": p.name, "point": p.point, "links": list(p.links)}
                   for p in m.pairs if p.kind in ("prismatic", "slot") and p.point]
        roles = {}
        if s is not None:
            roles = {k: getattr(s, k) for k in ("needle_point", "needle_eye", "take_up_eye",
                                                "shuttle_link", "shuttle_point", "feed_dog",
                                                "regulator") if getattr(s, k, None)}
            roles["plate_y"] = s.plate_y
            roles["fabric_thickness"] = s.fabric_thickness
        return {"name": m.name, "title": m.spec.machine.title, "file": self.file_name,
                "rpm": m.rpm, "points": list(m.point_names), "frame_points": frame,
                "links": links, "sliders": sliders, "roles": roles,
                "reference": {"phi_deg": m.spec.convention.reference_phi_deg,
                              "event": m.spec.convention.reference_event},
                "dynamics": self._dyn is not None, "dynamics_note": self.dynamics_note,
                "parameters": [p.to_dict() for p in self.table]}

    # ---- a design ------------------------------------------------------------------------------
    def design(self, values) -> np.ndarray:
        """The parameter vector of the page's values ({name: value in the shown unit})."""
        return self._design(values)[0]

    def _design(self, values) -> tuple[np.ndarray, dict[str, float]]:
        """(parameter vector, the changed dimensions in internal units) of the page's values."""
        if values is None:
            values = {}
        if not isinstance(values, dict):
            raise PageError("request", "'set' must be an object {name: value}",
                            "Send e.g. {\"set\": {\"needle_bar.length\": 45}}")
        overrides = {}
        for name, v in values.items():
            p = self.params.get(name)
            if p is None:
                shown = name if len(name) <= 60 else name[:57] + "..."
                raise ParameterError(shown, (), math.nan, "is not a parameter of machine"
                                     f" '{self.machine.name}'", "The parameter list names"
                                     " them all")
            if isinstance(v, bool) or not isinstance(v, int | float):
                raise ParameterError(name, (), math.nan, "must be a finite number, got"
                                     f" {_shown(v)}", "Send a number, e.g. 45.0")
            try:
                v = float(v)
            except OverflowError:  # an integer beyond every float (10**309)
                raise ParameterError(name, (), math.nan, "must be a finite number, got an"
                                     f" integer of {len(str(abs(v)))} digits", "Send a number"
                                     " inside the parameter's range") from None
            if not math.isfinite(v):
                raise ParameterError(name, (), math.nan, f"must be a finite number, got {v!r}",
                                     "Send a number inside the parameter's range")
            if (p.lo is not None and v < p.lo) or (p.hi is not None and v > p.hi):
                lo = "-inf" if p.lo is None else f"{p.lo:g}"
                hi = "inf" if p.hi is None else f"{p.hi:g}"
                raise ParameterError(name, (), float(v), f"is {v:g} {p.unit}: outside its range"
                                     f" {lo} .. {hi} {p.unit}", "Give a value inside it")
            overrides[name] = float(v) / p.factor
        inputs = {k[6:]: v for k, v in overrides.items() if k.startswith("input.")}
        dims = {k: v for k, v in overrides.items() if not k.startswith("input.")}
        try:
            return self.machine.parameters(dims, inputs=inputs), dims
        except SewmechError:
            raise
        except ValueError as exc:  # a cam's design values that make no cam
            cams = [k for k in dims if k.rpartition(".")[0] in self.machine.cam_designs]
            raise ParameterError(", ".join(cams) or "design", (), math.nan, str(exc),
                                 "Change the cam's width, stroke and dwell together") from None

    def validate_as_file(self, dims: dict[str, float]) -> None:
        """Check the changed dimensions as a machine file with them would be checked (the
        file's rules can be stricter than a parameter's domain, e.g. a crank's speed ratio of
        0); a located MachineFileError otherwise. The last set that passed is remembered."""
        key = tuple(sorted(dims.items()))
        if dims and key != getattr(self, "_valid", None):
            self._checks_machine.with_parameters(dims, origin="the page's values")
            self._valid = key

    def turn(self, values) -> dict:
        """One full turn of the design: every point, link and slider at each drawn angle, the
        motion diagrams, the feed (stitch length at the setting), the thread balance and the
        forces (driving torque, shaking force). Raises the library's located errors (an
        assembly that fails says which unit, at which angles, why)."""
        P = self.design(values)
        with self.lock:
            return plain(self._turn(P))

    def turn_json(self, values) -> bytes:
        """:meth:`turn` as compact JSON bytes, its arrays written at once (:mod:`.encode`):
        what the page receives. Written under the session's lock: the answer's arrays are
        views of the plans' own, which the next turn overwrites."""
        P = self.design(values)
        with self.lock:
            return dumps(self._turn(P))

    def _turn(self, P: np.ndarray) -> dict:
        m = self.machine
        out: dict = {"phi_deg": Arr(np.degrees(self.phi)), "rpm": m.rpm}
        if self._dyn is not None:
            d = self._dyn(P)
            kin = d.kin
            # the turn's means (the page's angles are a whole turn in equal steps)
            mean = (lambda x: float(np.mean(x)) if np.all(np.isfinite(x)) else None)
            fl = mean(d.friction_power) if d.friction is not None else None
            out["dynamics"] = {"torque_Nmm": Arr(d.input_torque),
                               "shaking_force_N": Arr(d.shaking_force),
                               "shaking_moment_Nmm": Arr(d.shaking_moment),
                               "mean_torque_Nmm": mean(d.input_torque),
                               "friction_loss_W": None if fl is None else fl * 1e-3,
                               "vibration": self._vibration(d)}
        else:
            kin = self._kin(P)
            out["dynamics"] = None
        out["points"] = {n: {"x": Arr(kin.p[:, i, 0]), "y": Arr(kin.p[:, i, 1])}
                         for i, n in enumerate(kin.point_names)}
        sl = []
        for p in m.pairs:
            if p.kind in ("prismatic", "slot") and p.point:
                th = kin.theta[:, m.link_index(p.line_link)] if p.line_link else 0.0
                ang = th + (P[p.line_param] if p.line_param >= 0 else 0.0) + p.extra_angle
                sl.append({"pair": p.name, "angle_deg": Arr(np.degrees(ang)
                                                                * np.ones(len(self.phi)))})
        out["sliders"] = sl
        out["motion"] = self._motion(kin)
        out["feed"], stitch = self._feed(P)
        out["thread"] = self._thread(P, stitch)
        return out

    def _vibration(self, d) -> dict | None:
        """The housing's vibration at its control points for this turn (the page's angles are a
        whole turn in equal steps: its Fourier series): name -> ``level_db`` and
        ``rms_velocity_mm_s``, each {x, y, z}; None without ``[housing]``."""
        if self._housing is None:
            return None
        from ...engine.housing import excitation, vibration

        h = self._housing
        W = excitation(self.machine, h, d)
        if not np.all(np.isfinite(W)):
            return None
        v = vibration(h, W, self.machine.rpm)
        rms, lv = v.rms_velocity, v.level_db
        return {name: {"level_db": {ax: _num(lv[i, j]) for j, ax in enumerate("xyz")},
                       "rms_velocity_mm_s": {ax: _num(rms[i, j]) for j, ax in enumerate("xyz")}}
                for i, name in enumerate(h.control_names)}

    def _motion(self, kin) -> dict:
        s = self.machine.spec.sewing
        series = {}
        if s is None:
            return series
        for key, label in (("needle_point", "needle point"), ("take_up_eye", "take-up eye")):
            name = getattr(s, key, None)
            if name:
                pm = kin.point(name)
                series[key] = {"label": label, "kind": "point", "name": name,
                               "y_mm": Arr(pm.p[:, 1]), "vy_mm_s": Arr(pm.v[:, 1]),
                               "ay_mm_s2": Arr(pm.a[:, 1])}
        if s.shuttle_link:
            lm = kin.link(s.shuttle_link)
            series["shuttle"] = {"label": "shuttle", "kind": "link", "name": s.shuttle_link,
                                 "theta_deg": Arr(np.degrees(np.unwrap(lm.theta))),
                                 "omega_rad_s": Arr(lm.omega),
                                 "epsilon_rad_s2": Arr(lm.epsilon)}
        return series

    def _feed(self, P: np.ndarray):
        from ...sewing.feed import feed_cycles

        s = self.machine.spec.sewing
        if s is None or not s.feed_dog or not s.regulator:
            return None, None
        reg_deg = math.degrees(P[self.machine.parameter_index(f"input.{s.regulator}")])
        try:
            c = feed_cycles(self.machine, reg_deg, params=P, step_deg=FEED_STEP_DEG)
        except SewmechError as exc:
            return {"error": error_dict(exc)}, None
        out = {"regulator_deg": _num(reg_deg), "phi_deg": Arr(c.phi_deg),
               "x_mm": Arr(c.x), "y_mm": Arr(c.y),
               **{k: _num(getattr(c, k)) for k in ("stitch_mm", "lift_mm", "drop_mm", "top_deg",
                                                    "rise_deg", "fall_deg", "stroke_mm",
                                                    "mid_feed_deg")}}
        if out["mid_feed_deg"] is None:
            out["note"] = "no feed at this setting: no mid-feed angle"
        return out, float(c.stitch_mm)

    def _thread(self, P: np.ndarray, stitch: float | None):
        from ...sewing.thread import check_thread, thread_balance

        m = self.machine
        t, s = m.spec.thread, m.spec.sewing
        if t is None or t.bobbin_case_radius is None or s is None or not s.shuttle_point:
            return None
        # the consumption follows the stitch at the setting; without feed, the library's 2.5 mm
        st = abs(stitch) if stitch is not None and abs(stitch) >= 0.1 else 2.5
        try:
            b = thread_balance(m, stitch_mm=st, params=P)
            checks = check_thread(m, b)
        except (SewmechError, ValueError) as exc:
            return {"error": error_dict(exc)}
        return {"stitch_mm": _num(st), "phi_deg": Arr(b.phi_deg),
                "supply_mm": Arr(b.supply), "demand_mm": Arr(b.demand),
                "overfeed_mm": Arr(b.overfeed),
                "events_deg": {k: _num(getattr(b, k)) for k in (
                    "take_up_top_deg", "seizure_deg", "cast_off_deg", "loop_max_deg",
                    "needle_entry_deg")},
                "consumption_mm": _num(b.consumption_mm),
                "checks": [check_dict(c) for c in checks]}

    def checks(self, values) -> dict:
        """The timing events (refined on the exact kinematics) and every check of the
        machine's roles: slower than a turn (tens of ms), so a request of its own. The design
        is also checked as a machine file with these values would be (:meth:`validate_as_file`),
        which a turn leaves out for speed."""
        from ...sewing import timing as T
        from ...sewing.checks import check_timing

        P, dims = self._design(values)
        m = self._checks_machine
        with self.checks_lock:
            self.validate_as_file(dims)
        s = m.spec.sewing
        if s is None:
            return {"events": [], "checks": [], "note": "the machine file has no [sewing]"}
        with self.checks_lock:
            events = []

            def event(name, fn):
                try:
                    value, unit = fn()
                    events.append({"event": name, "value": _num(value), "unit": unit})
                except (SewmechError, ValueError) as exc:
                    events.append({"event": name, "value": None, "unit": "",
                                   "error": error_dict(exc)})

            ns = T.needle_stroke(m, P)
            events += [{"event": "needle top dead centre", "value": _num(ns.top_phi_deg),
                        "unit": "deg"},
                       {"event": "needle bottom dead centre", "value": _num(ns.bottom_phi_deg),
                        "unit": "deg"},
                       {"event": "needle stroke", "value": _num(ns.stroke), "unit": "mm"}]
            try:
                w_in, _ = T.needle_windows(m, P)
                events += [{"event": "needle enters fabric", "value": _num(w_in.start_deg % 360),
                            "unit": "deg"},
                           {"event": "needle leaves fabric", "value": _num(w_in.end_deg % 360),
                            "unit": "deg"}]
            except (SewmechError, ValueError) as exc:
                events.append({"event": "needle in fabric", "value": None, "unit": "",
                               "error": error_dict(exc)})
            if s.shuttle_point:
                event("shuttle point meets needle", lambda: (T.loop_lift(m, P).phi_deg, "deg"))
                event("loop lift", lambda: (T.loop_lift(m, P).rise_mm, "mm"))
            if s.shuttle_link:
                event("shuttle swing", lambda: (T.shuttle_swing(m, P).swing_deg, "deg"))
            if s.take_up_eye:
                event("take-up eye top after needle top", lambda: (T.take_up_lag_deg(m, P),
                                                                   "deg"))
            try:
                checks = [check_dict(c) for c in check_timing(m, P, opening_speeds=False)]
                error = None
            except (SewmechError, ValueError) as exc:
                checks, error = [], error_dict(exc)
        return {"events": events, "checks": checks, "error": error}

    # ---- exports ---------------------------------------------------------------------------------
    def export_toml(self, values) -> str:
        """The machine file's own text with the page's values written in (comments and layout
        kept), checked by loading it back: its parameters are the design's. A file beyond
        :data:`EXPORT_IN_PLACE` is written anew from its values, with a note that says so."""
        import tomllib

        import tomlkit

        P = self.design(values)
        if self.in_place:
            doc = tomlkit.parse(self.text)
        else:
            doc = tomlkit.document()
            doc.add(tomlkit.comment(f"{self.file_name} with the page's values, written anew from"
                                    " its values: a file this large or with keys this dotted"
                                    " is not edited in place, so its comments are not kept"))
            doc.update(tomllib.loads(self.text))
        m = self.machine
        for name, v in (values or {}).items():
            cam, _, key = name.rpartition(".")
            if cam in m.cam_designs and key in _CAM_KEYS:
                path = ("cams", cam, "constant_width",
                        key if _CAM_KEYS[key] == "mm" else f"{key}_deg")
                x = float(v)
            else:
                i = m.parameter_index(name)
                path = m.parameter_sources[i]
                x = float(v)  # shown units are the file's units
            node = doc
            for part in path[:-1]:
                node = node[part]
            node[path[-1]] = x
        text = tomlkit.dumps(doc)
        back = machine_from_toml(text, self.file_name)
        if back.defaults.shape != P.shape or not np.allclose(back.defaults, P, rtol=1e-12,
                                                             atol=1e-9):
            bad = [n for n, a, b in zip(m.parameter_names, back.defaults, P)
                   if not math.isclose(a, b, rel_tol=1e-12, abs_tol=1e-9)]
            raise MachineFileError(self.file_name, "", "", "the exported file does not load"
                                   f" back to the page's design ({', '.join(bad[:5])} differ)",
                                   "This is a bug in sewmech: please report it")
        return text

    def drawing(self, values, phi_deg, fmt: str) -> str:
        """The page's design as a workshop drawing at the shaft angle ``phi_deg`` (the frame the
        page shows): DXF or SVG text, as ``sewmech export`` writes it."""
        import io

        import sewmech

        from ..drawing.cad import machine_drawing
        from ..files.cad import dxf_document, svg_text

        if isinstance(phi_deg, bool) or not isinstance(phi_deg, int | float) or \
                not math.isfinite(float(phi_deg)) or abs(float(phi_deg)) > 1e6:
            raise PageError("phi_deg", f"must be a finite shaft angle in deg, got"
                            f" {_shown(phi_deg)}", "Send e.g. {\"phi_deg\": 30}")
        P, dims = self._design(values)
        inputs = {n: float(P[self.machine.parameter_index(f"input.{n}")])
                  for n in self.machine.spec.inputs}
        d = machine_drawing(self.machine, phi_deg=float(phi_deg), params=P,
                            inputs=inputs or None, changes=dims, version=sewmech.__version__)
        if fmt == "svg":
            return svg_text(d)
        buf = io.StringIO()
        dxf_document(d).write(buf)
        return buf.getvalue()

    def curves_csv(self, values) -> str:
        """The current curves over the drawn turn as CSV (one row per shaft angle)."""
        import csv
        import io

        t = self.turn(values)
        cols: dict[str, list] = {"phi_deg": t["phi_deg"]}
        for sr in t["motion"].values():
            for k, v in sr.items():
                if isinstance(v, list):
                    cols[f"{sr['name']} {k}"] = v
        if t["dynamics"]:
            cols["torque_Nmm"] = t["dynamics"]["torque_Nmm"]
            f = t["dynamics"]["shaking_force_N"]
            cols["shaking_force_x_N"] = [r[0] for r in f]
            cols["shaking_force_y_N"] = [r[1] for r in f]
            cols["shaking_moment_Nmm"] = t["dynamics"]["shaking_moment_Nmm"]
        s = self.machine.spec.sewing
        if s is not None and s.feed_dog:
            cols["feed_dog_x_mm"] = t["points"][s.feed_dog]["x"]
            cols["feed_dog_y_mm"] = t["points"][s.feed_dog]["y"]
        buf = io.StringIO()
        w = csv.writer(buf, lineterminator="\n")
        w.writerow(cols)
        for row in zip(*cols.values()):
            w.writerow(["" if x is None else f"{x:.10g}" for x in row])
        return buf.getvalue()


def check_dict(c) -> dict:
    """A check as the page shows it; ``shown``: its value as the report shows it (at the
    precision of its quantity: the zero mark's stitch of round-off reads 0); ``references``:
    the entries its source's keys cite (key, source, url: docs/references.md)."""
    from ...sewing.references import cited
    from ..display import number_in

    return {"check": c.name, "value": _num(c.value), "unit": c.unit, "expected": c.expected,
            "shown": number_in(_num(c.value), c.unit),
            "passed": bool(c.passed), "source": c.source,
            "references": [r.brief() for r in cited(c.source)]}


def error_dict(exc: BaseException) -> dict:
    """A library error as the page shows it: where, what is wrong, what to do."""
    if isinstance(exc, SewmechError):
        return {"kind": type(exc).__name__, "where": exc.where or "",
                "what": exc.message or str(exc), "hint": exc.hint or ""}
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else str(exc)
    return {"kind": type(exc).__name__, "where": "", "what": str(text), "hint": ""}
