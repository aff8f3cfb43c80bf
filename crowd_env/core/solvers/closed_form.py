"""The paper's closed-form solutions of Section 3 (Kabalan et al. 2016), and the production solver on the same cases.

* Eq. 17-19: post-impact velocities of a head-on collision of two bodies as a function of K_n
  (:func:`head_on_analytic`; the elastic limit Eq. 18, :func:`head_on_elastic`), and the same impact by
  the production Frémond solver (:func:`head_on_numeric`, through
  :func:`~crowd_env.core.solvers.impact.solve_rows` with :func:`head_on_rows`): Fig. 5;
* Fig. 6: the spin θ̇₀ an oblique impact gives a pedestrian, by the production solver on two touching
  disks (:func:`oblique_rows`, :func:`oblique_spin`), as a function of K_tg (and its independence of K_n);
* Eq. 20-21: the heading after the impact for a critically damped heading spring, θ(t) = θ̇₀ t e^{−ωt} + θ_d
  (:func:`theta_analytic`) and its maximum θ_max = θ̇₀ / (ω e) + θ_d (:func:`theta_max`): Figs. 6-7.

The tests check the production solver and the simulator against these; ``crowd-collision-figures`` draws
the paper's figures from them.
"""
from __future__ import annotations

from crowd_env.errors import SolverError

import math

import numpy as np

from ..contacts import NORMAL, TANGENT
from .impact import solve_rows

PAPER_CASES = {
    "a": dict(m1=62.0, m2=62.0, u1=1.0, u2=-1.0),
    "b": dict(m1=62.0, m2=20.0, u1=2.0, u2=-0.5),
}
K_N_GRID = np.logspace(0.0, 6.0, 61)  # kg, the range of Fig. 5
K_TG_GRID = np.logspace(0.0, 6.0, 61)  # kg, the range of Fig. 6
RADIUS_M = 0.23
MASS_KG = 83.0


# ---------------------------------------------------------------- Fig. 5: head-on collision
def head_on_analytic(m1, m2, u1, u2, k_n):
    """Eq. 17-19: post-impact velocities of two point masses in a head-on collision."""
    mu = m1 * m2 / (m1 + m2)
    if k_n <= mu:
        common = (m1 * u1 + m2 * u2) / (m1 + m2)
        return common, common
    den = m1 * m2 + k_n * m1 + k_n * m2
    u1p = ((m1 * m2 + k_n * m1 - k_n * m2) * u1 + 2.0 * k_n * m2 * u2) / den
    u2p = ((m1 * m2 + k_n * m2 - k_n * m1) * u2 + 2.0 * k_n * m1 * u1) / den
    return u1p, u2p


def head_on_elastic(m1, m2, u1, u2):
    """Eq. 18: the limit K_n → ∞ (Eq. 19 when m1 = m2: the velocities are exchanged)."""
    return ((m1 - m2) * u1 + 2.0 * m2 * u2) / (m1 + m2), ((m2 - m1) * u2 + 2.0 * m1 * u1) / (m1 + m2)


def head_on_rows(k_n):
    """One normal row between body 0 (left, at x = 0) and body 1 (right): n from 1 to 0 is −x."""
    return (np.array([0]), np.array([1]), np.array([[-1.0, 0.0, 0.0]]), np.array([[1.0, 0.0, 0.0]]),
            np.array([float(k_n)]), np.array([NORMAL]))


def head_on_numeric(m1, m2, u1, u2, k_n):
    """Post-impact velocities and the reactive percussion from the production solver (solve_rows)."""
    mass_diag = np.array([m1, m1, 1.0, m2, m2, 1.0])
    v_minus = np.array([u1, 0.0, 0.0, u2, 0.0, 0.0])
    v_plus, lam, status = solve_rows(mass_diag, *head_on_rows(k_n), v_minus, np.zeros(6))
    if status != 0:
        raise SolverError(f"solver status {status}")
    return v_plus[0], v_plus[3], float(lam[0])


def fig5_data(case, k_values=K_N_GRID):
    """Arrays (K_n, u1⁺ numerical, u2⁺ numerical, u1⁺ analytic, u2⁺ analytic) for a paper case."""
    c = PAPER_CASES[case]
    num = np.array([head_on_numeric(c["m1"], c["m2"], c["u1"], c["u2"], k)[:2] for k in k_values])
    ana = np.array([head_on_analytic(c["m1"], c["m2"], c["u1"], c["u2"], k) for k in k_values])
    return np.asarray(k_values), num[:, 0], num[:, 1], ana[:, 0], ana[:, 1]


# ---------------------------------------------------------------- Fig. 6: spin from an oblique impact
def oblique_rows(k_n, k_tg, angle_rad, r1=RADIUS_M, r2=RADIUS_M):
    """Normal and tangent rows of two touching disks: body 1 sits at angle ``angle_rad`` from the
    direction of motion of body 0 (the common contact point divides the centre distance in the ratio
    of the radii, as :func:`~crowd_env.core.contacts.build_rows` places it)."""
    d = r1 + r2
    n = -np.array([math.cos(angle_rad), math.sin(angle_rad)])  # from body 1 to body 0
    t = np.array([-n[1], n[0]])
    rho0 = d * r1 / (r1 + r2)
    rho1 = d - rho0
    row_a = np.array([0, 0])
    row_b = np.array([1, 1])
    coef_a = np.array([[n[0], n[1], 0.0], [t[0], t[1], -rho0]])
    coef_b = np.array([[-n[0], -n[1], 0.0], [-t[0], -t[1], -rho1]])
    return row_a, row_b, coef_a, coef_b, np.array([float(k_n), float(k_tg)]), np.array([NORMAL, TANGENT])


def oblique_spin(k_tg, k_n=1.0e5, angle_deg=45.0, speed_m_s=1.0, mass_kg=MASS_KG, radius_m=RADIUS_M):
    """θ̇₀ (rad/s) of the moving pedestrian after it hits a pedestrian at rest obliquely (Fig. 6).

    Pedestrian 0 walks at ``speed_m_s`` along +x; pedestrian 1 touches it at ``angle_deg`` from that
    direction. Solid disks (I = m r²/2). Returns (θ̇₀ of 0, θ̇₀ of 1)."""
    inertia = 0.5 * mass_kg * radius_m ** 2
    mass_diag = np.array([mass_kg, mass_kg, inertia, mass_kg, mass_kg, inertia])
    v_minus = np.array([speed_m_s, 0.0, 0.0, 0.0, 0.0, 0.0])
    v_plus, _, status = solve_rows(mass_diag, *oblique_rows(k_n, k_tg, math.radians(angle_deg)), v_minus, np.zeros(6))
    if status != 0:
        raise SolverError(f"solver status {status}")
    return float(v_plus[2]), float(v_plus[5])


def fig6_data(k_values=K_TG_GRID, k_n=1.0e5, angle_deg=45.0):
    """(K_tg, θ̇₀) over the grid."""
    return np.asarray(k_values), np.array([oblique_spin(k, k_n=k_n, angle_deg=angle_deg)[0] for k in k_values])


# ---------------------------------------------------------------- Eq. 20-21, Fig. 7: heading after the impact
def natural_frequency(k, mass_kg=MASS_KG, radius_m=RADIUS_M):
    """ω = √(k / I) for a solid disk."""
    return math.sqrt(k / (0.5 * mass_kg * radius_m ** 2))


def theta_analytic(t, theta_dot0, k, theta_d=0.0, mass_kg=MASS_KG, radius_m=RADIUS_M):
    """Eq. 20: θ(t) = θ̇₀ t e^{−ωt} + θ_d (critically damped heading)."""
    w = natural_frequency(k, mass_kg, radius_m)
    return theta_dot0 * np.asarray(t) * np.exp(-w * np.asarray(t)) + theta_d


def theta_max(theta_dot0, k, theta_d=0.0, mass_kg=MASS_KG, radius_m=RADIUS_M):
    """Eq. 21: θ_max = θ̇₀ / (ω e) + θ_d."""
    return np.asarray(theta_dot0) / (natural_frequency(k, mass_kg, radius_m) * math.e) + theta_d


def fig7_data(theta_dot0_values, k_values=np.linspace(0.5, 18.5, 37)):
    """θ_max (rad) on the grid θ̇₀ × k (Eq. 21, θ_d = 0): arrays (θ̇₀, k, θ_max[k, θ̇₀])."""
    td = np.asarray(theta_dot0_values)
    kk = np.asarray(k_values)
    return td, kk, np.array([theta_max(td, k) for k in kk])
