"""The collision experiments of Kabalan et al. (2016), Section 3 (Figs. 5-7), run on the production code.

* Fig. 5: post-impact velocities of a head-on collision as a function of K_n, for the paper's two
  cases (62/62 kg at ±1 m/s; 62/20 kg at 2 and −0.5 m/s), numerical (the production Frémond solver)
  against the analytic Eq. 17-19.
* Fig. 6: spin θ̇₀ given to a pedestrian by an oblique impact as a function of K_tg (and its
  independence of K_n).
* Eq. 20 / Figs. 6-7: the heading after the impact, θ(t) = θ̇₀ t e^{−ωt} + θ_d for a critically
  damped heading (:func:`simulate_oblique_rotation`, the full Simulator, against the analytic curve),
  and the surface θ_max = θ̇₀ / (ω e) + θ_d over θ̇₀ and k ∈ [0.5, 18.5] (Eq. 21).

The closed forms and the solver's counterparts are :mod:`crowd_env.core.solvers.closed_form`; the
command is ``crowd-collision-figures`` (:mod:`crowd_env.cli.paper_collision_figures`).
"""
from __future__ import annotations

import math
import os

import numpy as np

from ...core import CrowdState, Simulator
from ...walking.model import ModelParams
from ...core.solvers.closed_form import (MASS_KG, PAPER_CASES, RADIUS_M, fig5_data, fig6_data, fig7_data,
                                                head_on_elastic, oblique_spin, theta_analytic, theta_max)


def simulate_oblique_rotation(k_tg, k, dt_s=0.01, t_end_s=4.0, k_n=1.0e5, angle_deg=45.0, speed_m_s=1.0):
    """Oblique impact followed by the heading's return, with the full :class:`Simulator`.

    Two touching pedestrians (pedestrian 1 at ``angle_deg`` from the direction of motion of
    pedestrian 0), headings and desired headings 0, τ huge so that translation is left alone, no
    social forces. The impact happens in the first step. Returns (times, θ of pedestrian 0, θ̇₀)
    with times measured from the impact (θ(0) = 0)."""
    a = math.radians(angle_deg)
    pos = np.array([[0.0, 0.0], [2 * RADIUS_M * math.cos(a), 2 * RADIUS_M * math.sin(a)]])
    state = CrowdState.create(pos, velocity_m_s=[[speed_m_s, 0.0], [0.0, 0.0]], mass_kg=MASS_KG, radius_m=RADIUS_M,
                              tau_s=1e12, heading_stiffness=k, desired_speed_m_s=1.0)
    params = ModelParams(dt_s=dt_s, normal_dissipation_kg=k_n, tangential_dissipation_kg=k_tg, social_forces=False)
    sim = Simulator(state, params=params)
    steps = int(round(t_end_s / dt_s))
    theta = np.zeros(steps + 1)
    zero = np.zeros(2)
    theta_dot0 = None
    for s in range(steps):
        sim.step(state.velocity_m_s.copy(), desired_heading_rad=zero)
        if theta_dot0 is None:
            theta_dot0 = float(state.angular_velocity_rad_s[0])
        theta[s + 1] = state.heading_rad[0]
    return np.arange(steps + 1) * dt_s, theta, theta_dot0


# ---------------------------------------------------------------- figures
def make_figures(out_dir):
    """Write the Fig. 5-7 PNGs into ``out_dir``, print the numbers behind them, return the paths."""
    from ...analysis.figures import pyplot, save_figure

    plt = pyplot()

    os.makedirs(out_dir, exist_ok=True)
    paths = []
    # Fig. 5
    fig, axes = plt.subplots(1, 2, figsize=(11, 4))
    print("Fig. 5: head-on collision, post-impact velocities (numerical | analytic Eq. 17-19)")
    for ax, case in zip(axes, ("a", "b")):
        c = PAPER_CASES[case]
        k, n1, n2, a1, a2 = fig5_data(case)
        ax.plot(np.log10(k), a1, "-", color="C0", label="u1+ analytical")
        ax.plot(np.log10(k), a2, "-", color="C1", label="u2+ analytical")
        ax.plot(np.log10(k)[::3], n1[::3], "o", color="C0", mfc="none", label="u1+ numerical")
        ax.plot(np.log10(k)[::3], n2[::3], "s", color="C1", mfc="none", label="u2+ numerical")
        mu = c["m1"] * c["m2"] / (c["m1"] + c["m2"])
        ax.axvline(math.log10(mu), color="grey", lw=0.8, ls=":", label=f"K_n = μ = {mu:.1f} kg")
        ax.set_xlabel("log10(K_n / kg)")
        ax.set_ylabel("u+ [m/s]")
        ax.set_title(f"({case}) m1={c['m1']:.0f}, m2={c['m2']:.0f} kg, u1-={c['u1']}, u2-={c['u2']} m/s")
        ax.legend(fontsize=7)
        err = max(np.abs(n1 - a1).max(), np.abs(n2 - a2).max())
        print(f"  case {case}: max |numerical - analytic| = {err:.2e} m/s over {k.size} K_n in [1e0, 1e6]; "
              f"K_n=1e0: u+=({n1[0]:+.4f}, {n2[0]:+.4f}); K_n=1e4: ({n1[40]:+.4f}, {n2[40]:+.4f}); "
              f"K_n=1e6: ({n1[-1]:+.4f}, {n2[-1]:+.4f}); elastic limit Eq. 18: "
              f"({head_on_elastic(c['m1'], c['m2'], c['u1'], c['u2'])[0]:+.4f}, "
              f"{head_on_elastic(c['m1'], c['m2'], c['u1'], c['u2'])[1]:+.4f})")
    paths.append(save_figure(fig, os.path.join(out_dir, "fig5_head_on.png")))
    # Fig. 6
    k_tg, td = fig6_data()
    fig, ax = plt.subplots(figsize=(5.5, 4))
    ax.plot(np.log10(k_tg), td, "-o", ms=3)
    for k_n in (2e3, 1e4, 1e6):
        ax.plot(np.log10(k_tg)[::6], fig6_data(k_tg[::6], k_n=k_n)[1], "x", label=f"K_n = {k_n:.0e} kg")
    ax.set_xlabel("log10(K_tg / kg)")
    ax.set_ylabel("θ̇₀ [rad/s]")
    ax.set_title("Spin after an oblique impact (45°, 1 m/s, 83 kg)")
    ax.legend(fontsize=7)
    paths.append(save_figure(fig, os.path.join(out_dir, "fig6_spin_vs_ktg.png")))
    print("Fig. 6: θ̇₀ [rad/s] after a 45° impact at 1 m/s (83 kg, r 0.23 m), K_n = 1e5 kg:")
    for k in (1e0, 1e1, 1e2, 1e3, 1e4, 1e5, 1e6):
        print(f"  K_tg = {k:8.0e} kg: θ̇₀ = {oblique_spin(k)[0]:+.5f}  (K_n = 2e3: {oblique_spin(k, k_n=2e3)[0]:+.5f})")
    # θ(t), Eq. 20
    fig, ax = plt.subplots(figsize=(5.5, 4))
    print("Eq. 20-21: heading after the impact, K_tg = 1e3 kg, full simulator (h = 0.01 s) vs analytic")
    for k in (0.5, 2.0, 5.0, 18.5):
        t, theta, td0 = simulate_oblique_rotation(1e3, k, dt_s=0.01, t_end_s=8.0)
        ax.plot(t, np.degrees(theta), label=f"k = {k}: simulated")
        ax.plot(t, np.degrees(theta_analytic(t, td0, k)), "k--", lw=0.8)
        print(f"  k = {k:5.1f}: θ̇₀ = {td0:+.5f} rad/s, θ_max simulated {np.degrees(np.abs(theta).max()):.3f}°, "
              f"Eq. 21 {np.degrees(abs(theta_max(td0, k))):.3f}°, max |θ - Eq. 20| = {np.degrees(np.abs(theta - theta_analytic(t, td0, k)).max()):.3f}°")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("θ [deg]")
    ax.set_title("Heading after the impact (dashed: Eq. 20)")
    ax.legend(fontsize=7)
    paths.append(save_figure(fig, os.path.join(out_dir, "fig6_theta_of_t.png")))
    # Fig. 7
    td_grid = np.linspace(0.0, max(abs(td.min()), abs(td.max())), 41)
    tdv, kk, surf = fig7_data(td_grid)
    fig, ax = plt.subplots(figsize=(5.5, 4))
    cs = ax.contourf(tdv, kk, np.degrees(surf), levels=20, cmap="viridis")
    ax.contour(tdv, kk, np.degrees(surf), levels=[5, 10, 20, 30], colors="w", linewidths=0.8)
    fig.colorbar(cs, label="θ_max [deg]")
    ax.set_xlabel("θ̇₀ [rad/s]")
    ax.set_ylabel("k [N m / rad]")
    ax.set_title("θ_max (Eq. 21)")
    paths.append(save_figure(fig, os.path.join(out_dir, "fig7_theta_max.png")))
    print(f"Fig. 7: θ_max over θ̇₀ in [0, {td_grid[-1]:.3f}] rad/s and k in [0.5, 18.5]: "
          f"max {np.degrees(surf.max()):.2f}° (k = 0.5), at k = 18.5: {np.degrees(surf[-1].max()):.2f}°")
    return paths

