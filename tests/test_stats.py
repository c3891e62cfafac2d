"""Block averaging (wallbatch.stats): white noise, AR(1) with a known correlation, NaN, shapes."""

import numpy as np
import pytest
from scipy.signal import lfilter

from wallbatch.stats import MIN_BLOCKS, ar1_sem, block_average, blocking_levels


def ar1(phi: float, n: int, rows: int, seed: int) -> np.ndarray:
    """Stationary AR(1) series x_t = phi x_{t-1} + eps_t (unit noise), `rows` independent rows."""
    eps = np.random.default_rng(seed).normal(size=(rows, n))
    eps[:, 0] /= np.sqrt(1.0 - phi ** 2)  # start in the stationary distribution
    return lfilter([1.0], [1.0, -phi], eps, axis=-1)


def test_white_noise_sem_is_std_over_sqrt_n():
    x = np.random.default_rng(7).normal(3.0, 2.0, size=2 ** 14)
    r = block_average(x)
    assert r.level == 0 and r.converged
    assert r.mean == pytest.approx(x.mean(), rel=1e-15)
    assert r.sem == pytest.approx(x.std(ddof=1) / np.sqrt(x.size), rel=1e-12)
    assert r.sem == pytest.approx(2.0 / np.sqrt(x.size), rel=0.03)  # the true value


def test_white_noise_many_rows_unbiased():
    x = np.random.default_rng(11).normal(size=(200, 4096))
    r = block_average(x)
    assert r.converged.mean() > 0.97
    ratio = r.sem * np.sqrt(4096)
    assert abs(ratio.mean() - 1.0) < 0.02  # sd of one ratio ~0.02-0.05, over 200 rows 0.004
    assert (r.level == 0).mean() > 0.8


@pytest.mark.parametrize("phi", [0.5, 0.9])
def test_ar1_sem_within_10_percent(phi):
    n = 2 ** 17
    x = ar1(phi, n, rows=1, seed=2026)[0]
    r = block_average(x)
    exact = ar1_sem(phi, 1.0, n)
    assert r.converged
    assert r.level > 0  # correlated: level 0 would be sqrt((1-phi)/(1+phi)) too small
    assert abs(r.sem / exact - 1.0) < 0.10
    naive = x.std() / np.sqrt(n)
    assert r.sem > 1.5 * naive


def test_ar1_unbiased_over_replicas():
    phi, n = 0.9, 2 ** 16
    x = ar1(phi, n, rows=64, seed=5)
    r = block_average(x)
    ratio = r.sem / ar1_sem(phi, 1.0, n)
    assert r.converged.all()
    assert abs(ratio.mean() - 1.0) < 0.05, ratio.mean()
    assert np.mean(abs(ratio - 1.0) < 0.10) > 0.8


def test_too_short_for_the_correlation_is_not_converged():
    # correlation time ~1000 samples, 16 of them in the series: no plateau
    x = ar1(0.999, 2 ** 14, rows=20, seed=3)
    r = block_average(x)
    assert not r.converged.any()
    assert (r.sem < ar1_sem(0.999, 1.0, 2 ** 14)).all()  # a lower bound, hence the flag


def test_few_samples_not_converged_but_finite():
    x = np.random.default_rng(1).normal(size=(3, 2 * MIN_BLOCKS - 1))
    r = block_average(x)
    assert not r.converged.any()
    assert np.allclose(r.sem, x.std(axis=-1, ddof=1) / np.sqrt(x.shape[-1]), rtol=1e-12)
    one = block_average(np.array([1.0]))
    assert np.isnan(one.sem) and not one.converged


def test_nan_series_and_leading_shape():
    x = np.random.default_rng(2).normal(size=(4, 5, 1024))
    x[1, 2, 10] = np.nan
    r = block_average(x)
    assert r.mean.shape == r.sem.shape == r.converged.shape == (4, 5)
    assert np.isnan(r.sem[1, 2]) and np.isnan(r.mean[1, 2]) and not r.converged[1, 2]
    assert np.isfinite(np.delete(r.sem.ravel(), 1 * 5 + 2)).all()
    # each row is processed as if alone (vectorisation does not mix series)
    alone = block_average(x[3, 4])
    assert alone.sem == r.sem[3, 4] and alone.level == r.level[3, 4]


def test_blocking_levels_closed_form():
    x = np.array([1.0, 3.0, 2.0, 6.0])
    s, e, n = blocking_levels(x)
    assert list(n) == [4, 2]
    assert s[0] == pytest.approx(np.sqrt(x.var() / 3))
    assert s[1] == pytest.approx(np.sqrt(np.var([2.0, 4.0]) / 1))
    assert e[0] == pytest.approx(s[0] / np.sqrt(6))


def test_ar1_closed_form_matches_direct_sum():
    phi, n = 0.7, 50
    var_x = 1.0 / (1 - phi ** 2)
    direct = var_x / n ** 2 * sum(phi ** abs(i - j) for i in range(n) for j in range(n))
    assert ar1_sem(phi, 1.0, n) == pytest.approx(np.sqrt(direct), rel=1e-12)


def test_pooled_windows_error_is_the_spread_of_replicas():
    """A profile bin's windows pooled by the atoms they counted (io.averages._pooled: the mean of a
    bin next to a wall, empty in some windows): windows of n ~ Poisson(2) atoms (0: empty, value 0
    as LAMMPS writes it), each the mean of its atoms' values (mean 1.5, sd 0.8). The pooled mean is
    the mean over every atom counted, and its ratio-estimator sem matches the spread of 4000
    independent replicas within 5% (the sampling error of that spread is ~2%)."""
    from wallbatch.io.averages import _pooled
    from wallbatch.io.results import Var

    rng = np.random.default_rng(11)
    reps, windows = 4000, 64
    n = rng.poisson(2.0, size=(reps, windows)).astype(float)
    with np.errstate(invalid="ignore", divide="ignore"):
        value = np.where(n > 0, 1.5 + 0.8 * rng.standard_normal((reps, windows)) / np.sqrt(n), 0.0)
    assert (n == 0).any(axis=1).mean() > 0.99  # nearly every replica has empty windows
    mean, sem, conv = _pooled(Var(("rep", "window"), value), Var(("rep", "window"), n), "window")
    np.testing.assert_allclose(mean.data, (n * value).sum(1) / n.sum(1), rtol=1e-12)
    assert abs(mean.data.mean() - 1.5) < 3 * 0.8 / np.sqrt(n.sum())  # unbiased
    spread = mean.data.std(ddof=1)
    assert abs(np.sqrt(np.mean(sem.data ** 2)) / spread - 1.0) < 0.05
    assert conv.data.mean() > 0.9
    none = _pooled(Var(("window",), np.zeros(8)), Var(("window",), np.zeros(8)), "window")
    assert np.isnan(none[0].data) and np.isnan(none[1].data) and not none[2].data
