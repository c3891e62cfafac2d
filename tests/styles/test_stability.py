"""Numerical stability of the flat-wall styles (issue 5 item 3): E, F and the shifted energy
E(r) - E(rc) against a 50-digit mpmath evaluation of the physics.md §4.1-4.6 closed forms, on a
few hundred random points per style and regime (near contact, mid range, near the cut-off,
colloid far field, Morse near r0, lengths scaled by 1e-60 .. 1e60).

What "well conditioned" means here. Every reference quantity Q is written as a sum of terms
Q = t_1 + t_2 + ... (below: ``_terms_*``), each a product/quotient/exp/log of the inputs with no
cancellation of its own, in the *natural variables* of the problem: r - R, rc - r and r - r0 are
inputs exactly as representable as r itself (Sterbenz: fl(r - rc) is exact for r in [rc/2, 2rc]),
so e.g. E(r) - E(rc) near rc is a well-conditioned function of (rc, rc - r) and its terms are the
differences of the monomials, c_n (sigma/r)^n - c_n (sigma/rc)^n, not E(r) and E(rc). Then a
relative perturbation u of the inputs changes each term by about k u |t_i| (k <= ~12, the power of
the term), hence Q by at most about k u S with S = sum |t_i|: the componentwise condition number
is kappa ~ S/|Q|. Where kappa <= 10 the problem is well conditioned and we require the relative
error |Q~ - Q|/|Q| <= 1e-13. Near a root of Q (a sign change of E, F or E(r) - E(rc) at r where
its terms balance) relative error is meaningless and we require |Q~ - Q| <= 1e-13 S/10 =
1e-14 S instead, i.e. in all cases

    |Q~ - Q| <= 1e-13 max(|Q|, S/10).

The same criterion applied to the plain E(r) - E(rc) fails near the cut-off (the error there is
~ u |E(rc)|, unrelated to S), and to the §4.6 colloid closed form in the far field (R/r -> 0).
"""

from __future__ import annotations

import mpmath
import numpy as np
import pytest

from wallbatch.styles.flat import STYLES

TOL = 1e-13
KAPPA = 10.0  # above this componentwise condition number S/|Q|, error is measured against S/KAPPA
N_POINTS = 400  # per style and regime
DPS = 50

# ---- references: the §4 closed forms, in mpmath, as lists of terms ----

mpf = mpmath.mpf


def _lj_terms(coef: list[tuple[float, int]], r, p, extra=None):
    """Terms of a sum of c (sigma/r)^n (+ extra(r)) for E, F = -dE/dr and E(r) - E(rc)."""
    eps, sigma, rc = mpf(p["epsilon"]), mpf(p["sigma"]), mpf(p["cutoff"])
    r = mpf(r)
    e = [eps * c * (sigma / r) ** n for c, n in coef]
    f = [eps * c * n * sigma**n / r ** (n + 1) for c, n in coef]
    de = [eps * c * ((sigma / r) ** n - (sigma / rc) ** n) for c, n in coef]
    if extra is not None:
        e2, f2, de2 = extra(r, eps, sigma, rc)
        e, f, de = e + [e2], f + [f2], de + [de2]
    return e, f, de


def _terms_lj93(r, p):
    return _lj_terms([(mpf(2) / 15, 9), (-1, 3)], r, p)


def _terms_lj126(r, p):
    return _lj_terms([(4, 12), (-4, 6)], r, p)


def _terms_lj1043(r, p):
    def wall3(r, eps, sigma, rc):  # -2 pi eps sqrt2 sigma^3 / (3 (r + s')^3), s' = 0.61/sqrt2 sigma
        shift = mpf("0.61") / mpmath.sqrt(2) * sigma
        k = -2 * mpmath.pi * eps * mpmath.sqrt(2) * sigma**3 / 3
        return k / (r + shift) ** 3, 3 * k / (r + shift) ** 4, k / (r + shift) ** 3 - k / (rc + shift) ** 3

    two_pi = 2 * mpmath.pi
    return _lj_terms([(two_pi * mpf(2) / 5, 10), (-two_pi, 4)], r, p, wall3)


def _terms_harmonic(r, p):
    eps, rc, r = mpf(p["epsilon"]), mpf(p["cutoff"]), mpf(r)
    e = eps * (r - rc) ** 2
    return [e], [2 * eps * (rc - r)], [e]


def _terms_morse(r, p):
    """Natural variable r - r0: F = 2 a D0 e^x (e^x - 1) is one term (no root cancellation
    counted near r0, where F is well conditioned in r - r0)."""
    d0, alpha, r0, rc = (mpf(p[k]) for k in ("D0", "alpha", "r0", "cutoff"))
    r = mpf(r)
    ex = mpmath.exp(-alpha * (r - r0))
    exc = mpmath.exp(-alpha * (rc - r0))
    e = [d0 * ex * (ex - 1), -d0 * ex]
    f = [2 * alpha * d0 * ex * (ex - 1)]
    de = [d0 * (ex - exc) * (ex - 1), d0 * (ex - exc) * (exc - 1)]
    return e, f, de


def _colloid_rep_att(r, big_r, sigma):
    """§4.6 as printed: A = sigma^6/7560 [(6R - D)/D^7 + (D + 8R)/(D + 2R)^7],
    B = [2R(D + R) + D(D + 2R)(ln D - ln(D + 2R))] / [D(D + 2R)], E = eps (A - B/6)."""
    d = r - big_r
    rep = sigma**6 / 7560 * ((6 * big_r - d) / d**7 + (d + 8 * big_r) / (d + 2 * big_r) ** 7)
    att = (2 * big_r * (d + big_r) + d * (d + 2 * big_r) * (mpmath.log(d) - mpmath.log(d + 2 * big_r))) / (
        d * (d + 2 * big_r))
    return rep, att


def _terms_colloid(r, p):
    eps, sigma, rc, big_r = (mpf(p[k]) for k in ("epsilon", "sigma", "cutoff", "radius"))
    r = mpf(r)
    rep, att = _colloid_rep_att(r, big_r, sigma)
    rep_c, att_c = _colloid_rep_att(rc, big_r, sigma)
    q = r * r - big_r * big_r
    f_rep = mpf(4) / 315 * eps * sigma**6 * (
        big_r**9 + 27 * big_r**7 * r**2 + 63 * big_r**5 * r**4 + 21 * big_r**3 * r**6) / q**8
    f_att = -mpf(2) / 3 * eps * big_r**3 / q**2
    return [eps * rep, -eps * att / 6], [f_rep, f_att], [eps * (rep - rep_c), -eps * (att - att_c) / 6]


TERMS = {"lj93": _terms_lj93, "lj126": _terms_lj126, "lj1043": _terms_lj1043, "harmonic": _terms_harmonic,
         "morse": _terms_morse, "colloid": _terms_colloid}


# ---- points: (r, params) arrays per style and regime, fixed seeds ----


def _logu(rng, lo, hi, n):
    return np.exp(rng.uniform(np.log(lo), np.log(hi), n))


def _near_cutoff(rng, rc, n):
    """r = rc (1 - 10^-k), k uniform in [1, 12]: within 1e-1 .. 1e-12 relative of rc."""
    return rc * (1.0 - 10.0 ** -rng.uniform(1.0, 12.0, n))


def _points_lj(regime: str, rng, n):
    eps = _logu(rng, 0.5, 3.0, n)
    sigma = _logu(rng, 0.5, 2.0, n)
    scale = 1.0
    if regime == "contact":  # deep in the repulsive wall
        r = sigma * _logu(rng, 0.05, 0.9, n)
        rc = sigma * _logu(rng, 1.0, 5.0, n)
    elif regime == "mid":  # through the minimum and both roots of E and F
        r = sigma * rng.uniform(0.6, 3.0, n)
        rc = r * (1.0 + _logu(rng, 0.05, 2.0, n))
    elif regime == "cutoff":  # rc anywhere from the repulsive wall to the far tail
        rc = sigma * _logu(rng, 0.5, 6.0, n)
        r = _near_cutoff(rng, rc, n)
    else:  # "scale": all lengths x 1e-60 .. 1e60, mid range and near the cut-off
        scale = 10.0 ** rng.choice([-60, -20, 20, 60], n)
        rc = sigma * _logu(rng, 0.7, 4.0, n)
        r = np.where(rng.random(n) < 0.5, rc * rng.uniform(0.2, 0.95, n), _near_cutoff(rng, rc, n))
    return r * scale, {"epsilon": eps, "sigma": sigma * scale, "cutoff": rc * scale}


def _points_harmonic(regime: str, rng, n):
    eps = _logu(rng, 0.5, 3.0, n)
    rc = _logu(rng, 0.5, 5.0, n)
    scale = 10.0 ** rng.choice([-60, -20, 20, 60], n) if regime == "scale" else 1.0
    r = {"contact": rc * _logu(rng, 1e-6, 0.1, n), "mid": rc * rng.uniform(0.1, 0.9, n)}.get(
        regime, _near_cutoff(rng, rc, n))
    return r * scale, {"epsilon": eps / scale**2, "sigma": np.ones(n), "cutoff": rc * scale}


def _points_morse(regime: str, rng, n):
    d0 = _logu(rng, 0.5, 3.0, n)
    alpha = _logu(rng, 1.0, 8.0, n)
    r0 = _logu(rng, 0.5, 3.0, n)
    scale = 1.0
    if regime == "contact":  # r from 0 to r0 - 0.1/alpha: e^x up to e^24
        r = r0 - rng.uniform(0.1, 0.99, n) * np.minimum(r0, 12.0 / alpha)
        rc = r0 + _logu(rng, 0.5, 10.0, n) / alpha
    elif regime == "near_r0":  # F -> 0 linearly: well conditioned in r - r0
        r = r0 * (1.0 + rng.choice([-1.0, 1.0], n) * 10.0 ** -rng.uniform(1.0, 12.0, n))
        rc = np.maximum(r, r0) + _logu(rng, 0.5, 10.0, n) / alpha
    elif regime == "mid":  # the attractive tail, down to e^-30
        r = r0 + rng.uniform(0.0, 30.0, n) / alpha
        rc = r + _logu(rng, 0.1, 5.0, n) / alpha
    elif regime == "cutoff":
        rc = np.maximum(r0 + rng.uniform(-0.5, 15.0, n) / alpha, 0.1 * r0)
        r = _near_cutoff(rng, rc, n)
    else:  # "scale"
        scale = 10.0 ** rng.choice([-60, -20, 20, 60], n)
        rc = r0 + _logu(rng, 0.5, 10.0, n) / alpha
        r = np.where(rng.random(n) < 0.5, rc * rng.uniform(0.3, 0.95, n), _near_cutoff(rng, rc, n))
    return r * scale, {"D0": d0, "alpha": alpha / scale, "r0": r0 * scale, "cutoff": rc * scale}


def _points_colloid(regime: str, rng, n):
    eps = _logu(rng, 0.5, 3.0, n)
    sigma = _logu(rng, 0.5, 2.0, n)
    big_r = sigma * _logu(rng, 0.2, 5.0, n)
    scale = 1.0
    if regime == "contact":  # surface gap D/R from 1 down to 1e-10
        r = big_r * (1.0 + 10.0 ** -rng.uniform(0.0, 10.0, n))
        rc = r + sigma * _logu(rng, 0.1, 5.0, n)
    elif regime == "mid":
        r = big_r + sigma * _logu(rng, 0.05, 5.0, n)
        rc = r + sigma * _logu(rng, 0.1, 5.0, n)
    elif regime == "far":  # R/r from 1e-1 down to 1e-6
        r = sigma * _logu(rng, 1.0, 20.0, n)
        big_r = r * _logu(rng, 1e-6, 1e-1, n)
        rc = r * (1.0 + _logu(rng, 0.01, 3.0, n))
    elif regime == "cutoff":  # R/rc from 0.9 (rc near contact) down to 1e-6 (far field)
        rc = big_r / _logu(rng, 1e-6, 0.9, n)
        r = _near_cutoff(rng, rc, n)
        r = np.where(r > big_r, r, rc)  # rc (1 - 1e-1) < R only when R/rc > 0.9: never
    else:  # "scale"
        scale = 10.0 ** rng.choice([-60, -20, 20, 60], n)
        rc = big_r + sigma * _logu(rng, 0.5, 5.0, n)
        r = np.where(rng.random(n) < 0.5, big_r + (rc - big_r) * rng.uniform(0.01, 0.95, n),
                     _near_cutoff(rng, rc, n))
    return r * scale, {"epsilon": eps, "sigma": sigma * scale, "cutoff": rc * scale, "radius": big_r * scale}


POINTS = {"lj93": _points_lj, "lj126": _points_lj, "lj1043": _points_lj, "harmonic": _points_harmonic,
          "morse": _points_morse, "colloid": _points_colloid}
REGIMES = {
    "lj93": ("contact", "mid", "cutoff", "scale"),
    "lj126": ("contact", "mid", "cutoff", "scale"),
    "lj1043": ("contact", "mid", "cutoff", "scale"),
    "harmonic": ("contact", "mid", "cutoff", "scale"),
    "morse": ("contact", "near_r0", "mid", "cutoff", "scale"),
    "colloid": ("contact", "mid", "far", "cutoff", "scale"),
}
CASES = [(name, regime) for name, regimes in REGIMES.items() for regime in regimes]


def sample(name: str, regime: str, n: int = N_POINTS):
    seed = [ord(ch) for ch in f"{name}/{regime}"]
    return POINTS[name](regime, np.random.default_rng(seed), n)


def reference(name: str, r: np.ndarray, p: dict) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """{quantity: (value, term scale S)} from the mpmath terms, per point."""
    out = {q: (np.empty(r.size), np.empty(r.size)) for q in ("E", "F", "dE")}
    with mpmath.workdps(DPS):
        for i in range(r.size):
            terms = TERMS[name](float(r[i]), {k: float(np.broadcast_to(v, r.shape)[i]) for k, v in p.items()})
            for q, ts in zip(("E", "F", "dE"), terms):
                out[q][0][i] = float(mpmath.fsum(ts))
                out[q][1][i] = float(mpmath.fsum(abs(t) for t in ts))
    return out


def scaled_errors(computed: dict[str, np.ndarray], ref) -> dict[str, tuple[float, float]]:
    """Per quantity: (max |Q~ - Q| / max(|Q|, S/KAPPA), max relative error where S <= KAPPA |Q|)."""
    out = {}
    for q, value in computed.items():
        exact, scale = ref[q]
        err = np.abs(np.asarray(value, dtype=float) - exact)
        with np.errstate(invalid="ignore", divide="ignore"):
            scaled = np.where(err == 0, 0.0, err / np.maximum(np.abs(exact), scale / KAPPA))
            good = scale <= KAPPA * np.abs(exact)
            rel = np.where(err[good] == 0, 0.0, err[good] / np.abs(exact[good]))
        out[q] = (float(np.max(np.where(np.isnan(scaled), np.inf, scaled))), float(rel.max(initial=0.0)))
    return out


@pytest.mark.parametrize("name, regime", CASES, ids=[f"{n}-{g}" for n, g in CASES])
def test_against_mpmath(name, regime):
    style = STYLES[name]
    r, p = sample(name, regime)
    assert np.all(r > style.too_close(p)) and np.all(r < p["cutoff"])
    ref = reference(name, r, p)
    energy, force = style.energy_force(r, p)
    computed = {"E": energy, "F": force, "dE": style.shifted_energy(r, p)}
    for q, (worst, worst_rel) in scaled_errors(computed, ref).items():
        assert worst <= TOL, f"{name} {regime} {q}: error {worst:.3g} x max(|Q|, S/{KAPPA:g})"
        assert worst_rel <= TOL


def test_criterion_rejects_the_plain_shift():
    """The criterion has teeth: E(r) - E(rc) by plain subtraction fails it near the cut-off."""
    style = STYLES["lj126"]
    r, p = sample("lj126", "cutoff", 40)
    ref = reference("lj126", r, p)
    plain = style.energy_force(r, p)[0] - style.energy_force(p["cutoff"], p)[0]
    assert scaled_errors({"dE": plain}, ref)["dE"][0] > 1e3 * TOL


def test_tiny_and_huge_lengths_are_finite():
    """Only ratios of lengths enter: sigma = r = 1e-20 (or 1e-150) is as good as 1."""
    for name in ("lj93", "lj126", "lj1043", "colloid"):
        base = {"epsilon": 1.0, "sigma": 1.0, "cutoff": 2.5, "radius": 0.5}
        r = np.array([0.8, 1.2, 2.4])
        e1, f1 = STYLES[name].energy_force(r, base)
        d1 = STYLES[name].shifted_energy(r, base)
        for scale in (1e-20, 1e-150, 1e150):
            p = {k: v * scale if k != "epsilon" else v for k, v in base.items()}
            e, f = STYLES[name].energy_force(r * scale, p)
            d = STYLES[name].shifted_energy(r * scale, p)
            np.testing.assert_allclose(e, e1, rtol=1e-14)
            np.testing.assert_allclose(f * scale, f1, rtol=1e-14)
            np.testing.assert_allclose(d, d1, rtol=1e-14)


def test_colloid_far_field_leading_order():
    """R/r -> 0: E -> -(2/9) eps (R/r)^3, F -> -(2/3) eps R^3/r^4 (attraction of a point-like sphere)."""
    r = np.array([1e3, 1e5, 1e7])
    p = {"epsilon": 1.3, "sigma": 1.0, "cutoff": 1e9, "radius": 1.0}
    energy, force = STYLES["colloid"].energy_force(r, p)
    np.testing.assert_allclose(energy, -(2.0 / 9.0) * 1.3 / r**3, rtol=3e-6)
    np.testing.assert_allclose(force, -(2.0 / 3.0) * 1.3 / r**4, rtol=3e-6)


# ---- through the engine: the reported wall energy of an atom 1e-9 rc inside the cut-off ----


def _lj126_wall_energy_in_run(monkeypatch, numba: bool) -> tuple[np.ndarray, float]:
    """wall_energy of one lj126 xlo wall over 4 steps, the atom at r = rc (1 - 1e-9) held still by
    a mass of 1e200 (v dt ~ 1e-202 does not move x); and the mpmath value of E(r) - E(rc)."""
    from wallbatch.config.models import config_from_dict
    from wallbatch.batch.runner import run_config

    monkeypatch.setenv("WALLBATCH_NUMBA", "1" if numba else "0")
    rc = 2.5
    x = rc * (1.0 - 1e-9)
    d = {"units": "lj", "seed": 11, "box": {"lo": [0, 0, 0], "hi": [10, 10, 10], "boundary": ["f", "f", "f"]},
         "atoms": [{"group": "a", "create": {"positions": [[x, 5.0, 5.0]]}, "mass": 1e200}],
         "walls": {"w": {"style": "lj126", "units": "box",
                         "xlo": {"coord": 0.0, "epsilon": 1.0, "sigma": 1.0, "cutoff": rc}}},
         "timestep": 0.005, "run": {"steps": 4, "thermo": 1}}
    ds = run_config(config_from_dict(d))
    assert ds.status.item() == "ok", ds.error.item()
    exact = reference("lj126", np.array([x]), {"epsilon": 1.0, "sigma": 1.0, "cutoff": rc})["dE"][0][0]
    return ds.wall_energy.values[:, 0], exact


def test_engine_reports_the_stable_shift(monkeypatch):
    energy, exact = _lj126_wall_energy_in_run(monkeypatch, numba=False)
    assert energy.shape == (5,)
    np.testing.assert_allclose(energy, exact, rtol=TOL, atol=0)


def test_compiled_path_reports_the_stable_shift(monkeypatch):
    """With the compiled chunks (fast.py, when numba is there) the sampled energies are the same."""
    energy, exact = _lj126_wall_energy_in_run(monkeypatch, numba=True)
    np.testing.assert_allclose(energy, exact, rtol=TOL, atol=0)
