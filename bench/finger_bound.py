"""The best any plan can do against a finger's friction dynamics: the least RMS error between the felt friction and
the target that any sequence of plate amplitudes reaches, knowing the whole future.

The finger is the simulated plate's (devices/sim/finger.py, its kernel ``friction_lag``): each control sample k its
felt ratio moves towards the settled ratio s_k = law(a_k) of the plate's amplitude a_k,

    y_k = y_(k-1) + c (s_k - y_(k-1)),   c = 1 - exp(-1 / (rate tau)),

tau the onset time constant where s_k < y_(k-1) and the recovery's (at the finger's speed) otherwise. The plate's
amplitude lies within 0 and its limit, so s_k within the law's floor (its value at the limit) and 1. Two figures
bracket the bound:

* **the bound** (the plate's envelope left out, any amplitude at once): a felt trajectory is reachable exactly
  when each step satisfies  -c_on (y_(k-1) - floor) <= y_k - y_(k-1) <= c_rec (1 - y_(k-1))  (the s that makes it
  is y_(k-1) + (y_k - y_(k-1)) / c, within floor..1, and the kernel takes the branch the step's sign says). The
  least squared error over that set is a convex quadratic programme with two linear constraints a sample, solved
  to optimality here by a primal-dual interior point whose Newton systems are tridiagonal. No plan does better,
  with the plate's envelope or without it (the envelope only removes amplitude sequences).
* **with the plate** (its envelope a_k = alpha a_(k-1) + (1 - alpha) d_k, the drive d within 0 and the drive
  ceiling, a_k within the limit): a drive sequence found by L-BFGS-B (analytic gradient), started from the bound's
  own plan, then felt through the finger's own kernel. A plan that exists: the least error lies between the two.

Independent of render/planning.py: nothing of the planner's is used, only the finger's law and kernel.

    from finger_bound import felt_bound
    best = felt_bound(target, scored, floor=0.168, c_onset=..., c_recovery=...)   # best.rms, best.felt, best.command
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import solveh_banded
from scipy.optimize import minimize
from ultraglide.devices.sim import kernels as finger_kernels
from ultraglide.devices.sim.finger import LIFTED_N, SLOWEST_RECOVERY_MM_S, FingerDynamics

FORCE_N = 0.5  # the bench's finger presses steadily (above LIFTED_N: always touching)


class BoundError(RuntimeError):
    """The bound's solver found no optimum (it ran out of iterations, or its Newton system failed): no bound."""


@dataclass(frozen=True)
class Bound:
    """A plan and what it is felt as: ``rms`` over the scored samples, ``felt`` and ``command`` (the settled ratio
    asked, s) per sample; ``solver_rms`` the optimiser's own figure (for the bound, the programme's optimum)."""

    rms: float
    solver_rms: float
    felt: np.ndarray
    command: np.ndarray
    iterations: int


def steps_per_sample(dynamics: FingerDynamics, speed_mm_s: float, rate_hz: float) -> tuple[float, float]:
    """(c_onset, c_recovery): the felt ratio's share of the way to the settled ratio per sample, as the finger's
    kernel has it (the recovery at the finger's speed, held at the slowest speed below it)."""
    v = max(speed_mm_s, SLOWEST_RECOVERY_MM_S)
    tau_rec = dynamics.recovery_s * (dynamics.reference_speed_mm_s / v) ** dynamics.speed_exponent
    return 1.0 - math.exp(-1.0 / (rate_hz * dynamics.onset_s)), 1.0 - math.exp(-1.0 / (rate_hz * tau_rec))


def feel(command: np.ndarray, dynamics: FingerDynamics, speed_mm_s: float, rate_hz: float,
         felt0: float = 1.0) -> np.ndarray:
    """The felt ratio for the settled ratios ``command``, by the simulated finger's own kernel."""
    command = np.ascontiguousarray(command, dtype=float)
    out = np.empty(len(command))
    finger_kernels.friction_lag(command, np.full(len(command), float(speed_mm_s)), np.full(len(command), FORCE_N),
                                LIFTED_N, float(rate_hz), dynamics.onset_s, dynamics.recovery_s,
                                dynamics.reference_speed_mm_s, dynamics.speed_exponent, SLOWEST_RECOVERY_MM_S,
                                float(felt0), out)
    return out


def felt_bound(target: np.ndarray, scored: np.ndarray, floor: float, c_onset: float, c_recovery: float,
               felt0: float = 1.0, tolerance: float = 1e-9, max_iterations: int = 200) -> Bound:
    """The least RMS error (over the ``scored`` samples) between the felt ratio and ``target`` that any settled
    ratios within ``floor``..1 reach, the felt ratio starting at ``felt0`` (see the module docstring).

    Returns the programme's optimum (``solver_rms``) and its plan felt again by the first-order law (``rms``,
    ``felt``; the two agree to the solver's tolerance). Raises BoundError (one line) where the solver does not
    converge within ``max_iterations`` or its Newton system cannot be factored (a recovery so slow the system is
    singular to rounding): an unconverged iterate is neither a bound nor a plan."""
    r = np.asarray(target, dtype=float)
    w = np.asarray(scored, dtype=float)
    n = len(r)
    if n < 2 or w.sum() == 0 or not (0.0 <= floor < 1.0) or not (0.0 < c_recovery <= 1.0 and 0.0 < c_onset <= 1.0):
        raise ValueError("a bound needs at least two samples, some scored, a floor in 0..1 and steps in 0..1")
    a_on, a_rec = 1.0 - c_onset, 1.0 - c_recovery
    # G y <= h, two rows a sample k (fall, rise), each on y_(k-1) and y_k; y_0 = felt0 moved into h.
    h_fall = np.full(n, -c_onset * floor)
    h_rise = np.full(n, c_recovery)
    h_fall[0] -= a_on * felt0
    h_rise[0] += a_rec * felt0
    h = np.concatenate((h_fall, h_rise))
    p = 2.0 * w + 1e-12  # the objective's Hessian (diagonal); the unscored samples' held positive by a hair
    q = -2.0 * w * r

    def g_times(x):  # G x
        prev = np.r_[0.0, x[:-1]]
        return np.concatenate((a_on * prev - x, x - a_rec * prev))

    def g_transposed(z):  # G^T z
        zf, zr = z[:n], z[n:]
        out = zr - zf
        out[:-1] += a_on * zf[1:] - a_rec * zr[1:]
        return out

    def newton_matrix(d):  # P + G^T diag(d) G, tridiagonal, in solveh_banded's upper form
        df, dr = d[:n], d[n:]
        band = np.zeros((2, n))
        band[1] = p + df + dr
        band[1, :-1] += a_on ** 2 * df[1:] + a_rec ** 2 * dr[1:]
        band[0, 1:] = -(a_on * df[1:] + a_rec * dr[1:])
        return band

    x = np.full(n, float(felt0))
    m = 2 * n
    s = np.maximum(h - g_times(x), 1e-3)
    z = np.ones(m)
    iterations = 0
    while True:
        rp = g_times(x) + s - h
        rd = p * x + q + g_transposed(z)
        mu = float(s @ z) / m
        if max(np.abs(rp).max(), np.abs(rd).max()) < tolerance and mu < tolerance * 1e-3:
            break
        if iterations == max_iterations:
            raise BoundError(f"the bound did not converge in {max_iterations} iterations (residual "
                             f"{max(np.abs(rp).max(), np.abs(rd).max()):.1e}, gap {mu:.1e}): no bound; raise "
                             f"max_iterations or loosen the tolerance")
        iterations += 1
        d = z / s
        band = newton_matrix(d)

        def direction(rc, band=band, rd=rd, rp=rp, d=d, s=s, z=z, iterations=iterations):
            try:
                dx = solveh_banded(band, -rd - g_transposed(d * rp + rc / s), check_finite=False)
            except np.linalg.LinAlgError:
                raise BoundError(f"the bound's Newton system is singular to rounding at iteration {iterations} "
                                 f"(c_onset {c_onset:g}, c_recovery {c_recovery:g}, felt0 {felt0:g}): no bound "
                                 f"at these parameters") from None
            dz = d * (g_times(dx) + rp) + rc / s
            return dx, dz, (rc - s * dz) / z

        dx, dz, ds = direction(-s * z)  # Mehrotra's predictor, then its corrector
        step = _longest(s, ds, z, dz)
        sigma = (float((s + step * ds) @ (z + step * dz)) / m / mu) ** 3
        dx, dz, ds = direction(-s * z - ds * dz + sigma * mu)
        step = min(1.0, 0.99 * _longest(s, ds, z, dz))
        x, s, z = x + step * dx, s + step * ds, z + step * dz
    solver_rms = math.sqrt(float(np.sum(w * (x - r) ** 2)) / w.sum())
    command = plan_for(x, floor, c_onset, c_recovery, felt0)
    felt = first_order(command, c_onset, c_recovery, felt0)
    return Bound(math.sqrt(float(np.sum(w * (felt - r) ** 2)) / w.sum()), solver_rms, felt, command, iterations)


def _longest(s, ds, z, dz) -> float:
    """The longest step (at most 1) that keeps the slacks and multipliers non-negative."""
    ratios = np.concatenate((-s[ds < 0] / ds[ds < 0], -z[dz < 0] / dz[dz < 0]))
    return min(1.0, float(ratios.min())) if len(ratios) else 1.0


def plan_for(felt: np.ndarray, floor: float, c_onset: float, c_recovery: float, felt0: float = 1.0) -> np.ndarray:
    """The settled ratios that make the felt trajectory ``felt`` (clipped to floor..1)."""
    before = np.r_[felt0, felt[:-1]]
    change = felt - before
    command = before + np.where(change < 0.0, change / c_onset, change / c_recovery)
    return np.clip(command, floor, 1.0)


def first_order(command: np.ndarray, c_onset: float, c_recovery: float, felt0: float = 1.0) -> np.ndarray:
    """The felt ratio for settled ratios ``command`` by the first-order law with the steps given."""
    felt = np.empty(len(command))
    y = felt0
    for k, x in enumerate(command.tolist()):
        y += (c_onset if x < y else c_recovery) * (x - y)
        felt[k] = y
    return felt


def plate_plan(target: np.ndarray, scored: np.ndarray, law, dynamics: FingerDynamics, speed_mm_s: float,
               rate_hz: float, tau_plate_s: float, limit_um_pp: float, drive_max_um_pp: float, start: np.ndarray,
               max_iterations: int = 300) -> Bound:
    """A drive sequence for a plate whose envelope lags (tau ``tau_plate_s``), found by L-BFGS-B from the settled
    ratios ``start`` (the bound's plan), and the error the finger's own kernel feels for it.

    The drive is parametrised per sample by where the plate's amplitude lands within what it can reach from the
    sample before, theta in 0..1: a_k = lo + theta (hi - lo), lo = alpha a_(k-1) (no drive), hi = min(alpha a_(k-1)
    + (1 - alpha) drive_max, limit). ``law(amplitude_um_pp)``: the settled ratio, falling with amplitude."""
    r = np.asarray(target, dtype=float)
    w = np.asarray(scored, dtype=float)
    n = len(r)
    alpha = math.exp(-1.0 / (rate_hz * tau_plate_s))
    push = (1.0 - alpha) * drive_max_um_pp
    c_on, c_rec = steps_per_sample(dynamics, speed_mm_s, rate_hz)
    grid = np.linspace(0.0, limit_um_pp, 6001)
    curve = law(grid)
    wanted = np.interp(-np.clip(start, curve[-1], 1.0), -curve, grid)  # the amplitude of each settled ratio

    def plate(theta):
        a = np.empty(n)
        lo = np.empty(n)
        span = np.empty(n)
        capped = np.empty(n, dtype=bool)
        prev = 0.0
        th = theta.tolist()
        for k in range(n):
            low = alpha * prev
            high = low + push
            cap = high > limit_um_pp
            if cap:
                high = limit_um_pp
            prev = low + th[k] * (high - low)
            a[k], lo[k], span[k], capped[k] = prev, low, high - low, cap
        return a, lo, span, capped

    def cost(theta):
        a, _, span, capped = plate(theta)
        s = np.clip(law(a), 0.0, 1.0)
        y = feel(s, dynamics, speed_mm_s, rate_hz)
        e = 2.0 * w * (y - r)
        before = np.r_[1.0, y[:-1]]
        c = np.where(s < before, c_on, c_rec)
        eps = 1e-5
        slope = (law(a + eps) - law(np.maximum(a - eps, 0.0))) / (a + eps - np.maximum(a - eps, 0.0))
        # adjoints, backwards: gy of y_k, ga of a_k
        grad = np.empty(n)
        keep = (1.0 - c).tolist()
        gain = (c * slope).tolist()
        carry = np.where(capped, alpha * (1.0 - theta), alpha).tolist()  # d a_k / d a_(k-1)
        el, sp = e.tolist(), span.tolist()
        gy = ga = 0.0
        for k in range(n - 1, -1, -1):
            gy = el[k] + gy * (keep[k + 1] if k + 1 < n else 0.0)
            ga = gy * gain[k] + ga * (carry[k + 1] if k + 1 < n else 0.0)
            grad[k] = ga * sp[k]
        return float(np.sum(w * (y - r) ** 2)), grad

    theta0 = np.empty(n)  # the bound's amplitudes, as near as the plate follows them
    prev = 0.0
    for k in range(n):
        low = alpha * prev
        high = min(low + push, limit_um_pp)
        theta0[k] = min(max((wanted[k] - low) / (high - low), 0.0), 1.0) if high > low else 0.0
        prev = low + theta0[k] * (high - low)
    fit = minimize(cost, theta0, jac=True, method="L-BFGS-B", bounds=[(0.0, 1.0)] * n,
                   options={"maxiter": max_iterations, "maxcor": 20})
    theta = fit.x if fit.fun <= cost(theta0)[0] else theta0
    a = plate(theta)[0]
    s = np.clip(law(a), 0.0, 1.0)
    y = feel(s, dynamics, speed_mm_s, rate_hz)
    rms = math.sqrt(float(np.sum(w * (y - r) ** 2)) / w.sum())
    return Bound(rms, math.sqrt(fit.fun / w.sum()), y, s, int(fit.nit))


def case_bounds(target: np.ndarray, scored: np.ndarray, law, dynamics: FingerDynamics, speed_mm_s: float,
                rate_hz: float, limit_um_pp: float, tau_plate_s: float, drive_max_um_pp: float,
                plate_iterations: int = 300) -> tuple[Bound, Bound]:
    """The bound (no envelope) and the best plan found with the plate's envelope, for one bench case.
    ``law(amplitude_um_pp)``: the finger's settled ratio (its floor is its value at ``limit_um_pp``)."""
    grid = np.linspace(0.0, limit_um_pp, 6001)
    floor = float(np.min(law(grid)))
    c_on, c_rec = steps_per_sample(dynamics, speed_mm_s, rate_hz)
    bound = felt_bound(target, scored, floor, c_on, c_rec)
    with_plate = plate_plan(target, scored, law, dynamics, speed_mm_s, rate_hz, tau_plate_s, limit_um_pp,
                            drive_max_um_pp, bound.command, plate_iterations)
    return bound, with_plate


if __name__ == "__main__":
    for speed in (50.0, 100.0, 200.0):  # the step 1 -> 0.3 -> 1 with settled ratios held within 0.3..1: by hand
        rate = 12000.0
        c_on, c_rec = steps_per_sample(FingerDynamics(), speed, rate)
        t = np.arange(int(0.6 * rate)) / rate
        target = np.where((t >= 0.1) & (t < 0.3), 0.3, 1.0)
        try:
            best = felt_bound(target, np.ones(len(t)), 0.3, c_on, c_rec)
        except BoundError as error:
            raise SystemExit(f"finger_bound: {error}") from None
        tau = -1.0 / (rate * math.log(1.0 - c_rec))
        hand = math.sqrt(0.49 * (FingerDynamics().onset_s + tau) * (math.log(2.0) - 0.5) / 0.6)
        print(speed, round(best.solver_rms, 5), round(best.rms, 5), "by hand", round(hand, 5), best.iterations)
