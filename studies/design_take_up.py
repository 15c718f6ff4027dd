"""Design study: the take-up four-bar of a JB machine file for a balanced needle thread.

This is how the take-up of ``jb1-3.toml`` and ``jb8-2.toml`` was found (see the notes beside
``take_up.eye`` in those files). It searches the take-up's eight dimensions (crank pin T, rocker
pivot Q, lever and rocker lengths, the eye on the lever) with differential evolution, scoring
each batch of designs on the thread balance of ``sewmech.thread`` (docs/references.md) at 0.5 deg:

- overfeed >= 0.5 mm while the shuttle enlarges the loop;
- 0.5-9 mm of overfeed when the needle enters the fabric (the check spring takes it);
- a reserve of at least the consumption + 1 mm once the loop is cast off;
- the eye's top 15..LAG_MAX deg after the needle's, and within 10 deg of the thread's top;

and on soundness: a take-up crank of at most 20 mm, the eye above the face-plate guides
(y >= -35 mm), in front of the needle bar (x 10..80 mm) and moving mostly vertically (x travel
<= 40 mm), and a least transmission angle between lever and rocker of MU_MIN (default 25 deg;
without it the search runs to the change-point four-bar, whose lever nearly locks). A small
weight on the largest overfeed keeps slack low.

Run: ``.venv/bin/python studies/design_take_up.py jb1-3 --seed 31 --lag-max 40`` (about a
minute on two cores). Prints the dimensions and the balance figures; changes no file.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.optimize import differential_evolution

import sewmech
from sewmech.thread import thread_balance, thread_path

NAMES = ["T.u", "T.v", "Q.x", "Q.y", "take_up.length1", "take_up.length2", "take_up.eye.u",
         "take_up.eye.v"]
LOWER = np.array([3, -25, -80, -30, 10, 8, -100, -30.0])
UPPER = np.array([25, 25, 20, 60, 80, 60, -10, 30.0])
STEP_DEG = 0.5


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("machine")
    ap.add_argument("--seed", type=int, default=31)
    ap.add_argument("--lag-max", type=float, default=40.0)
    ap.add_argument("--mu-min", type=float, default=25.0, help="least transmission angle, deg")
    args = ap.parse_args()
    m = sewmech.load_machine(args.machine)
    b0 = thread_balance(m, step_deg=STEP_DEG)  # the demand does not depend on the take-up
    phi = np.radians(b0.phi_deg)
    d_raw = b0.bar + b0.penetration + b0.loop
    grow = (b0.phi_deg - b0.seizure_deg) % 360 <= (b0.loop_max_deg - b0.seizure_deg) % 360
    k_entry = int(round(b0.needle_entry_deg / STEP_DEG)) % len(phi)
    k_cast = int(round(b0.cast_off_deg / STEP_DEG)) % len(phi)
    y_needle = sewmech.kinematics(m, phi, points=["needle.point"]).point("needle.point").p[:, 1]
    k_needle_top = int(np.argmax(y_needle))

    def evaluate(X):
        P = m.parameters({k: X[:, i] for i, k in enumerate(NAMES)})
        tp = thread_path(m, phi, params=P, on_failure="mask")
        r = sewmech.kinematics(m, phi, params=P, points=["take_up.eye"],
                               links=["take_up_lever", "take_up_rocker"], variables=[],
                               on_failure="mask")
        rel = np.abs(np.angle(np.exp(1j * (r.link("take_up_lever").theta
                                           - r.link("take_up_rocker").theta))))
        mu = np.degrees(np.minimum(rel, np.pi - rel)).min(axis=-1)  # least transmission angle
        return tp.supply, r.point("take_up.eye").p, mu

    def score(XT):
        X = np.atleast_2d(XT.T)
        S, eye, mu = evaluate(X)
        ok = (np.all(np.isfinite(S), axis=-1) & np.all(np.isfinite(eye[..., 1]), axis=-1)
              & np.isfinite(mu))
        S = np.where(ok[:, None], S, 0.0)
        ex = np.where(ok[:, None], eye[..., 0], 50.0)
        ey = np.where(ok[:, None], eye[..., 1], 0.0)
        k_top = np.argmin(np.where(ok[:, None], S, 1e9), axis=-1)
        k_eye = np.argmax(ey, axis=-1)
        O = S - (d_raw[None, :] - d_raw[k_top][:, None])
        f = 10 * np.maximum(0, 0.5 - np.where(grow[None, :], O, 1e9).min(axis=-1))
        f += 10 * np.maximum(0, O[:, k_entry] - 9.0) + 10 * np.maximum(0, 0.5 - O[:, k_entry])
        f += 10 * np.maximum(0, b0.consumption_mm + 1.0 - O[:, k_cast])
        lag = ((k_eye - k_needle_top) * STEP_DEG + 180) % 360 - 180
        f += 10 * np.maximum(0, 15 - lag) + 10 * np.maximum(0, lag - args.lag_max)
        f += 2 * np.maximum(0, np.abs(((k_eye - k_top) * STEP_DEG + 180) % 360 - 180) - 10)
        f += 0.02 * O.max(axis=-1)
        f += 10 * np.maximum(0, np.hypot(X[:, 0], X[:, 1]) - 20.0)
        f += 5 * np.maximum(0, -35.0 - ey.min(axis=-1))
        f += 5 * np.maximum(0, 10.0 - ex.min(axis=-1)) + 5 * np.maximum(0, ex.max(axis=-1) - 80.0)
        f += 5 * np.maximum(0, np.ptp(ex, axis=-1) - 40.0)
        f += 5 * np.maximum(0, args.mu_min - np.where(ok, mu, 0.0))
        f[~ok] = 1e6
        return f

    x0 = np.array([m.defaults[m.parameter_index(k)] for k in NAMES])
    t0 = time.perf_counter()
    res = differential_evolution(score, list(zip(LOWER, UPPER)), vectorized=True,
                                 updating="deferred", popsize=25, maxiter=300, seed=args.seed,
                                 tol=1e-10, polish=False, x0=np.clip(x0, LOWER, UPPER))
    x = np.round(res.x, 1)
    P = m.parameters({k: x[i] for i, k in enumerate(NAMES)})
    b = thread_balance(m, step_deg=STEP_DEG, params=P)
    print(f"{args.machine}: {time.perf_counter() - t0:.0f} s, score {res.fun:.3f}")
    for k, v in zip(NAMES, x):
        print(f"  {k:18s} {v:8.1f} mm")
    print(f"  least overfeed while the loop grows {b.min_overfeed_while_loop_grows:.2f} mm,"
          f" at needle entry {b.overfeed_at_needle_entry:.2f} mm, reserve after cast-off"
          f" {b.reserve_after_cast_off:.1f} mm, thread stroke {np.ptp(b.supply):.1f} mm")
    print(f"  eye top after needle top: {sewmech.timing.take_up_lag_deg(m, P):.1f} deg;"
          f" least transmission angle {float(evaluate(x[None, :])[2][0]):.1f} deg")


if __name__ == "__main__":
    main()
