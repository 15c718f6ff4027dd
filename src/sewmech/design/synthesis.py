"""Classical synthesis of four-bar linkages: function generation (Freudenstein), motion
generation (Burmester, three and four positions), timed path generation (an exact start for the
optimiser), and the machine file of the answer.

Conventions. The four-bar is A (input pivot), B (input link's moving pivot), C (output link's
moving pivot), D (output pivot); a = AB (input), b = BC (coupler), c = DC (output), d = AD
(ground). Angles are counter-clockwise, rad inside (``*_deg`` at the edges), lengths mm. In
function generation A = (0, 0) and D = (d, 0), and the input and output angles theta2, theta4 are
those of A -> B and D -> C from +x, so Freudenstein's equation reads

    K1 cos(theta4) - K2 cos(theta2) + K3 = cos(theta2 - theta4),
    K1 = d / a, K2 = d / c, K3 = (a^2 - b^2 + c^2 + d^2) / (2 a c),

linear in K1..K3: three precision points fix them, more give a least-squares fit. A negative
a or c (K1 or K2 < 0) is a link that points the other way: its length is |a| and B sits at
u = -|a| on the input link, which keeps theta2 as the link's angle. ``branch`` is the engine's
(``rrr`` unit): +1 puts C to the left of the directed line B -> D.

The defects classical synthesis is known for are found and named, never returned silently:
precision points on different assembly branches (circuits; the branch defect), a dead centre of
the input between them, positions reached out of order (the order defect), an input that must
turn fully but cannot (Grashof), and requirements no four-bar meets. Each is a
:class:`SynthesisError` that says which requirement and what to change.
"""

from __future__ import annotations

import ast
import math
import operator
from dataclasses import dataclass, field

import numpy as np

from ..engine.errors import SewmechError

TWO_PI = 2.0 * math.pi


class SynthesisError(SewmechError, ValueError):
    """Requirements that no four-bar (of the kind asked for) meets, or input that cannot be
    synthesised (coincident precision points, a function that is not finite, ...). ``where``
    names the requirement (the option or argument)."""


# ---- the four-bar ----------------------------------------------------------------------------


GRASHOF_KINDS = {
    "crank-rocker": "crank-rocker (the input turns fully, the output rocks)",
    "double-crank": "double crank (drag link: input and output turn fully)",
    "rocker-crank": "rocker-crank (the output turns fully, the input rocks)",
    "double-rocker": "Grashof double rocker (the coupler turns fully, input and output rock)",
    "triple-rocker": "non-Grashof triple rocker (no link turns fully)",
}


@dataclass(frozen=True)
class Grashof:
    """Grashof's classification of a four-bar with lengths a (input), b (coupler), c (output),
    d (ground): s + l against p + q (shortest, longest, the other two)."""

    kind: str
    s_plus_l: float
    p_plus_q: float
    change_point: bool

    @property
    def input_turns(self) -> bool:
        return self.kind in ("crank-rocker", "double-crank")

    @property
    def text(self) -> str:
        extra = " (a change point: s + l = p + q, it can fold flat)" if self.change_point else ""
        return GRASHOF_KINDS[self.kind] + extra


def grashof(a: float, b: float, c: float, d: float, rtol: float = 1e-9) -> Grashof:
    """Grashof type of the four-bar a (input), b (coupler), c (output), d (ground), mm."""
    lengths = {"input": a, "coupler": b, "output": c, "ground": d}
    order = sorted(lengths, key=lengths.get)
    s, p, q, lng = (lengths[k] for k in order)
    sl, pq = s + lng, p + q
    change = abs(sl - pq) <= rtol * pq
    if sl > pq and not change:
        return Grashof("triple-rocker", sl, pq, False)
    shortest = order[0]
    kind = {"input": "crank-rocker", "ground": "double-crank", "output": "rocker-crank",
            "coupler": "double-rocker"}[shortest]
    return Grashof(kind, sl, pq, change)


@dataclass(frozen=True)
class FourBar:
    """A planar four-bar. A, D : (2,) frame pivots, mm; a, b, c : input, coupler and output
    lengths, mm (> 0); input_u, output_u : +a or -a (+c or -c), where B (C) sits on the input
    (output) link's u axis, so that the link's angle is theta2 (theta4) whatever the sign;
    branch : the engine's assembly branch (+1: C left of B -> D); coupler_point : (u, v) of a
    point on the coupler in the coupler's frame (origin B, u along B -> C), or None."""

    A: tuple[float, float]
    D: tuple[float, float]
    a: float
    b: float
    c: float
    input_u: float
    output_u: float
    branch: int
    coupler_point: tuple[float, float] | None = None
    phase: float = 0.0

    @property
    def d(self) -> float:
        return float(math.hypot(self.D[0] - self.A[0], self.D[1] - self.A[1]))

    @property
    def grashof(self) -> Grashof:
        return grashof(self.a, self.b, self.c, self.d)

    def solve(self, theta2: np.ndarray, branch: int | None = None) -> dict:
        """Closed-form position at input angles ``theta2`` (rad): B, C (..., 2), theta4 (the
        output link's angle, rad), theta3 (the coupler's), ok (assembled), h2 (the squared
        height of C over B -> D: 0 at a dead centre)."""
        t = np.asarray(theta2, dtype=float) + self.phase
        br = self.branch if branch is None else branch
        A = np.asarray(self.A, dtype=float)
        D = np.asarray(self.D, dtype=float)
        B = A + self.input_u * np.stack([np.cos(t), np.sin(t)], axis=-1)
        dvec = D - B
        dd2 = np.sum(dvec * dvec, axis=-1)
        dd = np.sqrt(dd2)
        e = dvec / dd[..., None]
        along = (self.b ** 2 - self.c ** 2 + dd2) / (2.0 * dd)
        h2 = self.b ** 2 - along ** 2
        h = br * np.sqrt(np.maximum(h2, 0.0))
        C = B + along[..., None] * e + h[..., None] * np.stack([-e[..., 1], e[..., 0]], -1)
        rc = C - D
        theta4 = np.arctan2(rc[..., 1], rc[..., 0]) - (0.0 if self.output_u > 0 else math.pi)
        bc = C - B
        theta3 = np.arctan2(bc[..., 1], bc[..., 0])
        return {"B": B, "C": C, "theta4": theta4, "theta3": theta3, "ok": h2 > 0.0, "h2": h2}

    def transmission_deg(self, theta2: np.ndarray) -> np.ndarray:
        """The transmission angle (between coupler and output link, folded into 0..90 deg) at
        the input angles ``theta2``, deg."""
        s = self.solve(theta2)
        u = s["C"] - s["B"]
        w = s["C"] - np.asarray(self.D)
        cosm = np.sum(u * w, -1) / (np.linalg.norm(u, axis=-1) * np.linalg.norm(w, axis=-1))
        mu = np.degrees(np.arccos(np.clip(cosm, -1.0, 1.0)))
        return np.minimum(mu, 180.0 - mu)

    def coupler_xy(self, theta2: np.ndarray) -> np.ndarray:
        """The coupler point's position at the input angles ``theta2`` (..., 2), mm."""
        s = self.solve(theta2)
        u, v = self.coupler_point or (0.0, 0.0)
        c3, s3 = np.cos(s["theta3"]), np.sin(s["theta3"])
        return s["B"] + np.stack([u * c3 - v * s3, u * s3 + v * c3], axis=-1)


def _fmt(x: float) -> str:
    """A number as the machine file writes it: every digit a float has (repr)."""
    x = float(x)
    return repr(0.0 if x == 0.0 else x)


def machine_text(fb: FourBar, *, name: str, title: str, notes: list[str],
                 drive: str = "shaft", input_range_deg: tuple[float, float] | None = None,
                 ratio: int = 1, phase_deg: float = 0.0) -> str:
    """The machine file (TOML text) of ``fb``: frame points A and D, the input link ``input``
    (a crank turned by the shaft, ``drive="shaft"``: its angle phase + ratio phi; or, for an
    input that cannot turn fully, ``drive="setting"``: a setting input ``input`` over
    ``input_range_deg``), the ``rrr`` dyad (links ``coupler`` and ``output``), and the coupler
    point P when ``fb`` has one. ``notes``: comment lines for the head of the file."""
    head = "".join(f"# {line}\n" for line in notes)
    if drive == "shaft":
        conv = (f'reference_event = "input link at {_fmt(phase_deg)} deg"\n'
                f"reference_phi_deg = 0.0\nreference_link = \"input\"\n"
                f"reference_angle_deg = {_fmt(phase_deg)}\n")
        crank = (f'[[units]]\ntype = "crank"\nname = "input"\npivot = "A"\n'
                 f"phase_deg = {_fmt(phase_deg)}\n"
                 + (f"ratio = {ratio}\n" if ratio != 1 else "")
                 + f"points = {{ B = [{_fmt(fb.input_u)}, 0.0] }}\n")
        inputs = ""
    else:
        lo, hi = input_range_deg
        mid = 0.5 * (lo + hi)
        conv = (f'reference_event = "input lever at mid-range, {_fmt(mid)} deg (a setting'
                f' input: the shaft turns nothing)"\nreference_phi_deg = 0.0\n'
                f'reference_link = "input"\nreference_angle_deg = {_fmt(mid)}\n')
        inputs = (f"[inputs.input]\ndefault_deg = {_fmt(mid)}\nmin_deg = {_fmt(lo)}\n"
                  f"max_deg = {_fmt(hi)}\n\n")
        crank = (f'[[units]]\ntype = "crank"\nname = "input"\npivot = "A"\ninput = "input"\n'
                 f"phase_deg = 0.0\npoints = {{ B = [{_fmt(fb.input_u)}, 0.0] }}\n")
    text = (f"{head}\n[machine]\nname = \"{name}\"\ntitle = \"{title}\"\n\n[convention]\n{conv}\n"
            f"[speed]\nrpm = 1000.0\n\n{inputs}"
            f"[points.A]\nx = {_fmt(fb.A[0])}\ny = {_fmt(fb.A[1])}\n\n"
            f"[points.D]\nx = {_fmt(fb.D[0])}\ny = {_fmt(fb.D[1])}\n\n{crank}\n"
            f'[[units]]\ntype = "rrr"\nname = "dyad"\njoints = ["B", "D"]\nnew = "C"\n'
            f'links = ["coupler", "output"]\nlengths = [{_fmt(fb.b)}, {_fmt(fb.c)}]\n'
            f"branch = {int(fb.branch)}\n")
    if fb.coupler_point is not None:
        u, v = fb.coupler_point
        text += (f'\n[[units]]\ntype = "point"\nname = "coupler_point"\nlink = "coupler"\n'
                 f'origin = "B"\npoints = {{ P = [{_fmt(u)}, {_fmt(v)}] }}\n')
    return text


# ---- function generation (Freudenstein) ------------------------------------------------------


def chebyshev_spacing(x0: float, xf: float, n: int) -> np.ndarray:
    """Chebyshev's precision points on [x0, xf]: x_j = (x0 + xf)/2 - (xf - x0)/2
    cos((2 j - 1) pi / (2 n)), j = 1..n (the zeros of T_n mapped onto the range)."""
    j = np.arange(1, n + 1)
    return 0.5 * (x0 + xf) - 0.5 * (xf - x0) * np.cos((2 * j - 1) * math.pi / (2 * n))


def freudenstein_k(theta2: np.ndarray, theta4: np.ndarray, where: str = "precision points"
                   ) -> tuple[np.ndarray, float]:
    """K1, K2, K3 of Freudenstein's equation from input and output angles (rad): exact for
    three pairs, least squares for more. Returns (K, rms residual of the equation)."""
    t2 = np.asarray(theta2, dtype=float)
    t4 = np.asarray(theta4, dtype=float)
    n = t2.size
    if n < 3 or t4.size != n:
        raise SynthesisError(where, f"{n} input angles and {t4.size} output angles: Freudenstein's"
                             " equation needs at least three pairs", "Give three or more")
    key = np.round(np.stack([np.mod(t2, TWO_PI), np.mod(t4, TWO_PI)], -1), 12)
    for i in range(n):
        for j in range(i):
            if np.all(np.abs(key[i] - key[j]) < 1e-9):
                raise SynthesisError(where, f"precision points {j + 1} and {i + 1} coincide"
                                     f" (input {math.degrees(t2[i]):.6g} deg, output"
                                     f" {math.degrees(t4[i]):.6g} deg)",
                                     "Give distinct points: each fixes one equation")
    M = np.stack([np.cos(t4), -np.cos(t2), np.ones(n)], axis=1)
    rhs = np.cos(t2 - t4)
    sv = np.linalg.svd(M, compute_uv=False)
    if sv[-1] <= 1e-10 * sv[0]:
        raise SynthesisError(where, "the precision points do not fix a four-bar (Freudenstein's"
                             " equations are dependent: equal input or output angles)",
                             "Spread the points over the ranges")
    K, *_ = np.linalg.lstsq(M, rhs, rcond=None)
    res = M @ K - rhs
    return K, float(np.sqrt(np.mean(res * res)))


def lengths_from_k(K: np.ndarray, d: float) -> tuple[float, float, float]:
    """Signed input a, coupler b and signed output c from K1..K3 and the ground d (mm)."""
    K1, K2, K3 = (float(k) for k in K)
    if K1 == 0.0 or K2 == 0.0:
        raise SynthesisError("precision points", "K1 or K2 is 0: an input or output link of"
                             " infinite length (a slider)", "Change the ranges")
    a, c = d / K1, d / K2
    b2 = a * a + c * c + d * d - 2.0 * a * c * K3
    if not b2 > 0.0:
        raise SynthesisError("precision points", f"no four-bar meets them: the coupler's length"
                             f" squared comes out {b2:.4g} mm^2", "Change the ranges or their"
                             " starting angles")
    return a, math.sqrt(b2), c


_FUNCS = {"sin": np.sin, "cos": np.cos, "tan": np.tan, "exp": np.exp, "log": np.log,
          "ln": np.log, "log10": np.log10, "sqrt": np.sqrt, "abs": np.abs, "arctan": np.arctan,
          "atan": np.arctan, "sinh": np.sinh, "cosh": np.cosh, "tanh": np.tanh}
_CONSTS = {"pi": math.pi, "e": math.e}
_BINOPS = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv, ast.Pow: operator.pow}


def function_of_x(text: str, where: str = "--function"):
    """A function y = f(x) from text such as ``log10(x)`` or ``x**1.5``: numbers, x, pi, e,
    + - * / ** and the functions of :data:`_FUNCS` only (parsed, never executed as code)."""
    if len(text) > 500:
        raise SynthesisError(where, "is longer than 500 characters", "Write the function shorter")
    try:
        tree = ast.parse(text.strip(), mode="eval")
    except SyntaxError:
        raise SynthesisError(where, f"{text!r} is not a formula in x", "Write e.g. 'log10(x)'"
                             " or 'x**1.5'") from None

    def check(node):
        if isinstance(node, ast.Expression):
            return check(node.body)
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) \
                and not isinstance(node.value, bool):
            return
        if isinstance(node, ast.Name) and (node.id == "x" or node.id in _CONSTS):
            return
        if isinstance(node, ast.BinOp) and type(node.op) in _BINOPS:
            check(node.left)
            check(node.right)
            return
        if isinstance(node, ast.UnaryOp) and isinstance(node.op, (ast.USub, ast.UAdd)):
            check(node.operand)
            return
        if isinstance(node, ast.Call) and isinstance(node.func, ast.Name) \
                and node.func.id in _FUNCS and len(node.args) == 1 and not node.keywords:
            check(node.args[0])
            return
        raise SynthesisError(where, f"{text!r}: {ast.unparse(node)!r} is not allowed", "Use"
                             f" numbers, x, pi, e, + - * / ** and {', '.join(_FUNCS)}")

    check(tree)

    def ev(node, x):
        if isinstance(node, ast.Expression):
            return ev(node.body, x)
        if isinstance(node, ast.Constant):
            return float(node.value)
        if isinstance(node, ast.Name):
            return x if node.id == "x" else _CONSTS[node.id]
        if isinstance(node, ast.BinOp):
            return _BINOPS[type(node.op)](ev(node.left, x), ev(node.right, x))
        if isinstance(node, ast.UnaryOp):
            v = ev(node.operand, x)
            return -v if isinstance(node.op, ast.USub) else v
        return _FUNCS[node.func.id](ev(node.args[0], x))

    def f(x):
        xa = np.asarray(x, dtype=float)
        with np.errstate(all="ignore"):
            y = np.asarray(ev(tree, xa), dtype=float) + np.zeros_like(xa)
        return y

    return f


@dataclass(frozen=True)
class FunctionSynthesis:
    """A four-bar function generator and how well it meets its function.

    fourbar : the linkage (A = (0, 0), D = (d, 0)); K : Freudenstein's K1..K3; method :
    "three points" or "least squares"; x, y : the precision points (the function's values);
    theta2_deg, theta4_deg : the angles there; residual_rms : rms of Freudenstein's equation at
    the points; grashof : its type; x_grid, error : the structural error y_generated - f(x)
    over the range (units of y), error_deg : the same in output degrees; notes : the free
    choices and findings, stated."""

    fourbar: FourBar
    K: np.ndarray
    method: str
    function: str
    x_range: tuple[float, float]
    input_range_deg: tuple[float, float]
    output_range_deg: tuple[float, float]
    x: np.ndarray
    y: np.ndarray
    theta2_deg: np.ndarray
    theta4_deg: np.ndarray
    residual_rms: float
    grashof: Grashof
    x_grid: np.ndarray
    y_generated: np.ndarray
    error: np.ndarray
    error_deg: np.ndarray
    min_transmission_deg: float
    notes: tuple[str, ...] = field(default_factory=tuple)

    @property
    def max_error(self) -> float:
        return float(np.max(np.abs(self.error)))

    @property
    def max_error_deg(self) -> float:
        return float(np.max(np.abs(self.error_deg)))


def _assemblies_at(fb: FourBar, theta2: np.ndarray, theta4: np.ndarray) -> np.ndarray:
    """The branch (+1, -1) on which ``fb`` has output angle theta4 at input theta2 (rad), for
    each pair; 0 where neither (never, for Freudenstein's own points)."""
    out = np.zeros(np.size(theta2), dtype=int)
    for br in (1, -1):
        s = fb.solve(theta2, br)
        gap = np.abs(np.angle(np.exp(1j * (s["theta4"] - theta4))))
        out[(out == 0) & (gap < 1e-7)] = br
    return out


def synthesize_function(function: str, x_range: tuple[float, float],
                        input_range_deg: tuple[float, float],
                        output_range_deg: tuple[float, float], *, ground_mm: float = 100.0,
                        points: int = 3, spacing: str = "chebyshev",
                        x_points: np.ndarray | None = None, grid: int = 721
                        ) -> FunctionSynthesis:
    """A four-bar whose output angle follows y = f(x) while its input angle follows x.

    x in ``x_range`` maps linearly onto the input angles ``input_range_deg`` (start, end) and
    y = f(x) from f(x0) to f(xf) onto the output angles ``output_range_deg``. With ``points`` =
    3 the four-bar meets the function exactly at three precision points (``spacing``
    "chebyshev" or "even", or ``x_points`` given); with more, Freudenstein's equation is met
    in the least-squares sense at that many evenly spaced points. The structural error is
    evaluated on ``grid`` points over the range, on the assembly branch that passes through
    the precision points.

    Raises SynthesisError: the function not finite or constant over the range, coincident
    points, no real four-bar, precision points on different branches (the branch defect), a
    dead centre of the input inside the range, a full-turn input that cannot turn, an output
    range beyond what a rocker can swing.
    """
    f = function_of_x(function)
    x0, xf = (float(v) for v in x_range)
    if not (math.isfinite(x0) and math.isfinite(xf)) or x0 == xf:
        raise SynthesisError("--x-range", f"{x0:g} .. {xf:g} is not a range", "Give two"
                             " different finite values")
    t2s, t2f = (math.radians(v) for v in input_range_deg)
    t4s, t4f = (math.radians(v) for v in output_range_deg)
    if t2s == t2f or t4s == t4f or not all(map(math.isfinite, (t2s, t2f, t4s, t4f))):
        raise SynthesisError("--input-range-deg/--output-range-deg", "a range of zero width",
                             "Give the start and the end angle of each link's travel")
    full_turn = abs(t2f - t2s) >= TWO_PI - 1e-12
    if full_turn and TWO_PI - 1e-12 > abs(t4f - t4s) >= math.pi:
        raise SynthesisError("--output-range-deg", f"the output swings"
                             f" {math.degrees(abs(t4f - t4s)):g} deg while the input turns"
                             " fully: no crank-rocker does (its rocker swings less than 180"
                             " deg)", "Give an output range under 180 deg, or a full turn"
                             " (a double crank)")
    y0, yf = float(f(x0)), float(f(xf))
    if not (math.isfinite(y0) and math.isfinite(yf)) or y0 == yf:
        raise SynthesisError("--function", f"f({x0:g}) = {y0:g} and f({xf:g}) = {yf:g}: the"
                             " output range cannot be mapped onto it", "Give a function that is"
                             " finite at both ends and differs between them")
    notes = [f"x in {x0:g} .. {xf:g} maps onto the input angle"
             f" {math.degrees(t2s):g} .. {math.degrees(t2f):g} deg and y = {function} from"
             f" {y0:.6g} to {yf:.6g} onto the output angle {math.degrees(t4s):g} .."
             f" {math.degrees(t4f):g} deg (free choices, stated)",
             f"ground AD = {ground_mm:g} mm along +x (a free choice: it scales the linkage)"]
    if x_points is not None:
        xs = np.asarray(x_points, dtype=float)
        method = "three points" if xs.size == 3 else "least squares"
        notes.append(f"precision points given: x = {', '.join(f'{v:.6g}' for v in xs)}")
    elif points == 3:
        if spacing not in ("chebyshev", "even"):
            raise SynthesisError("--spacing", f"{spacing!r} is not chebyshev or even")
        xs = (chebyshev_spacing(x0, xf, 3) if spacing == "chebyshev"
              else np.linspace(x0, xf, 5)[1:-1])
        method = "three points"
        notes.append(f"precision points by {spacing} spacing: x ="
                     f" {', '.join(f'{v:.6g}' for v in xs)}")
    else:
        if points < 3:
            raise SynthesisError("--points", f"{points} points: three at least")
        xs = np.linspace(x0, xf, points)
        method = "least squares"
        notes.append(f"least squares over {points} evenly spaced points, ends included")
    ys = f(xs)
    if not np.all(np.isfinite(ys)):
        raise SynthesisError("--function", f"{function} is not finite at x ="
                             f" {xs[~np.isfinite(ys)][0]:g}", "Choose a range where it is")
    t2 = t2s + (xs - x0) / (xf - x0) * (t2f - t2s)
    t4 = t4s + (ys - y0) / (yf - y0) * (t4f - t4s)
    K, rms = freudenstein_k(t2, t4)
    a, b, c = lengths_from_k(K, ground_mm)
    fb0 = FourBar((0.0, 0.0), (ground_mm, 0.0), abs(a), b, abs(c), a, c, 1)
    br = _assemblies_at(fb0, t2, t4) if method == "three points" else None
    if br is None:  # least squares: the branch that meets the points best
        errs = []
        for cand in (1, -1):
            s = fb0.solve(t2, cand)
            errs.append(np.nanmax(np.abs(np.angle(np.exp(1j * (s["theta4"] - t4))))
                                  + np.where(s["ok"], 0.0, np.inf)))
        branch = 1 if errs[0] <= errs[1] else -1
    else:
        if np.any(br == 0) or np.unique(br).size > 1:
            on = ", ".join(f"point {k + 1}: {'+1' if v > 0 else '-1' if v < 0 else 'none'}"
                           for k, v in enumerate(br))
            raise SynthesisError("precision points", "branch defect: the four-bar through them"
                                 f" meets them on different assembly branches ({on}), so no"
                                 " motion passes through all three", "Change the angle ranges"
                                 " (their starts or widths) or the spacing")
        branch = int(br[0])
    fb = FourBar((0.0, 0.0), (ground_mm, 0.0), abs(a), b, abs(c), a, c, branch)
    g = fb.grashof
    if full_turn and not g.input_turns:
        raise SynthesisError("--input-range-deg", f"the input must turn fully, but the four-bar"
                             f" through the precision points is a {g.text}", "Give an input"
                             " range under a full turn, or other ranges")
    xg = np.linspace(x0, xf, grid)
    t2g = t2s + (xg - x0) / (xf - x0) * (t2f - t2s)
    s = fb.solve(t2g)
    if not np.all(s["ok"]):
        k = int(np.argmin(s["ok"]))
        raise SynthesisError("--input-range-deg", f"the four-bar through the precision points"
                             f" reaches a dead centre at input {math.degrees(t2g[k]):.6g} deg"
                             f" (x = {xg[k]:.6g}) inside the range and cannot move on there",
                             "Narrow the input range or change the output range")
    t4g = t4s + np.unwrap(s["theta4"] - t4s - np.round((s["theta4"][0] - t4s) / TWO_PI)
                          * TWO_PI)
    t4g -= np.round((t4g[0] - t4s) / TWO_PI) * TWO_PI
    yg = y0 + (t4g - t4s) / (t4f - t4s) * (yf - y0)
    err = yg - f(xg)
    err_deg = np.degrees(err / (yf - y0) * (t4f - t4s))
    notes.append(f"assembly branch {branch:+d} (C {'left' if branch > 0 else 'right'} of"
                 f" B -> D) through every precision point; Grashof: {g.text}")
    if a < 0 or c < 0:
        notes.append("K1 or K2 came out negative: "
                     + ", ".join(n for n, v in (("the input", a), ("the output", c)) if v < 0)
                     + " link points away from its angle (B or C at u = -length), which keeps"
                       " the angles as asked")
    mu = fb.transmission_deg(t2g)
    return FunctionSynthesis(fb, K, method, function, (x0, xf), tuple(input_range_deg),
                             tuple(output_range_deg), xs, ys, np.degrees(t2), np.degrees(t4),
                             rms, g, xg, yg, err, err_deg, float(mu.min()), tuple(notes))
