"""Time averages with error bars: block averaging (Flyvbjerg & Petersen, J. Chem. Phys. 91, 461
(1989)) vectorised over any leading axes (cases, faces, bins).

A series x_1..x_n of correlated samples has a mean whose standard error is not std/sqrt(n).
Blocking transforms the series level by level: level 0 is the series, level k+1 averages
neighbouring pairs of level k (a trailing odd value is dropped). At each level with n_k values
of variance c_k (1/n_k normalisation) the estimate of the standard error of the mean is

    s_k = sqrt(c_k / (n_k - 1)),    with its own error  ds_k = s_k / sqrt(2 (n_k - 1)).

s_k grows with k while the blocks are shorter than the correlation time and then stays flat (the
plateau) at the true standard error.

Plateau rule used here (deterministic, documented in docs/howto/profiles.md):
  * a level is *usable* when it has at least `min_blocks` values (default 16);
  * a usable level k is *on the plateau* when it has a later usable level and no later usable
    level lies significantly above it: s_j <= s_k + z ds_j for every usable j > k (z = 2.5);
  * if level 0 is on the plateau the samples look uncorrelated: sem = s_0;
  * otherwise the reported level is the first level on the plateau whose block length B = 2^k
    also meets the optimal-block criterion of Lee et al. (Phys. Rev. E 83, 066706
    (2011)), B^3 > 2 n (s_k / s_0)^4, which balances the bias of short blocks (~ tau / B)
    against the noise of few blocks; `converged` is True;
  * when no level qualifies (fewer than 2 * min_blocks samples, or the estimate still grows at
    the last usable levels), `converged` is False and the reported sem is the largest s_k over
    the usable levels (s_0 when no level is usable): a lower bound, flagged as such.

For white noise every level agrees, so the plateau is level 0 and sem = s_0 = std/sqrt(n) (the sample
standard deviation with n - 1 over sqrt(n)).  All values are in the units of the series.
A series with a NaN (a failed case) gives NaN mean and sem and converged False.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_BLOCKS = 16  # values a blocking level needs to count (its sem is then known to ~18%)
Z_PLATEAU = 2.5  # how many of its own error bars a later level may rise before it breaks the plateau


@dataclass(frozen=True)
class BlockAverage:
    """Result of `block_average` over the last axis; arrays have the leading shape of the input.

    mean: the sample mean; sem: standard error of the mean (plateau value); converged: a plateau
    was found; level: the blocking level reported (block length 2**level samples, -1 for NaN
    series); levels_sem / levels_err: s_k and ds_k per level on a trailing axis (NaN past the
    last level with two values).
    """

    mean: np.ndarray
    sem: np.ndarray
    converged: np.ndarray
    level: np.ndarray
    levels_sem: np.ndarray
    levels_err: np.ndarray


def blocking_levels(x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """s_k, ds_k and n_k for every blocking level of the series on the last axis of `x`.

    Returns (sem (..., K), err (..., K), counts (K,)) for levels k = 0..K-1 with n_k >= 2.
    """
    x = np.asarray(x, dtype=float)
    sems, errs, counts = [], [], []
    level = x
    while level.shape[-1] >= 2:
        n = level.shape[-1]
        var = level.var(axis=-1)  # 1/n normalisation
        s = np.sqrt(var / (n - 1))
        sems.append(s)
        errs.append(s / np.sqrt(2.0 * (n - 1)))
        counts.append(n)
        m = n // 2
        level = 0.5 * (level[..., 0:2 * m:2] + level[..., 1:2 * m:2])
    if not sems:
        shape = x.shape[:-1] + (0,)
        return np.zeros(shape), np.zeros(shape), np.zeros(0, dtype=np.int64)
    return np.stack(sems, axis=-1), np.stack(errs, axis=-1), np.asarray(counts, dtype=np.int64)


def block_average(x: np.ndarray, min_blocks: int = MIN_BLOCKS, z: float = Z_PLATEAU) -> BlockAverage:
    """Mean, blocked standard error and plateau flag of the series on the last axis of `x`.

    Vectorised: `x` may be (n,), (C, n), (C, n, F) moved to (C, F, n), ... Any leading shape.
    """
    x = np.asarray(x, dtype=float)
    lead = x.shape[:-1]
    n = x.shape[-1]
    with np.errstate(invalid="ignore", divide="ignore"):
        mean = x.mean(axis=-1) if n else np.full(lead, np.nan)
        sem_k, err_k, counts = blocking_levels(x)
    usable = counts >= min_blocks  # (K,), a prefix of the levels
    nu = int(usable.sum())
    K = len(counts)
    level = np.full(lead, -1, dtype=np.int64)
    converged = np.zeros(lead, dtype=bool)
    if nu >= 2:
        s = sem_k[..., :nu]
        e = err_k[..., :nu]
        # on[..., k]: level k has a later usable level and none of them lies significantly above it
        on = np.zeros(lead + (nu,), dtype=bool)
        for k in range(nu - 1):  # a loop over levels (at most log2 n), vectorised over the series
            on[..., k] = ~(s[..., k + 1:] > s[..., k:k + 1] + z * e[..., k + 1:]).any(axis=-1)
        # Lee et al.'s optimal block length: B^3 > 2 n (s_B / s_0)^4 (bias ~ tau/B against noise)
        block = 2.0 ** np.arange(nu)
        with np.errstate(invalid="ignore", divide="ignore"):
            lee = block ** 3 > 2.0 * n * (s / s[..., :1]) ** 4
        pick = np.where(on[..., :1], on & (np.arange(nu) == 0), on & lee)
        found = pick.any(axis=-1)
        first = np.argmax(pick, axis=-1)
        plateau = np.take_along_axis(s, first[..., None], axis=-1)[..., 0]
        sem = np.where(found, plateau, np.max(s, axis=-1))
        level = np.where(found, first, np.argmax(s, axis=-1)).astype(np.int64)
        converged = found & np.isfinite(sem)
    elif K >= 1:
        sem = sem_k[..., 0]
        level = np.zeros(lead, dtype=np.int64)
    else:
        sem = np.full(lead, np.nan)
    bad = ~np.isfinite(mean) | ~np.isfinite(sem)
    if np.ndim(bad):
        sem = np.where(bad, np.nan, sem)
        mean = np.where(bad, np.nan, mean)
        level = np.where(bad, -1, level)
        converged = converged & ~bad
    elif bad:
        sem, mean, level, converged = np.float64(np.nan), np.float64(np.nan), np.int64(-1), np.bool_(False)
    return BlockAverage(mean=np.asarray(mean), sem=np.asarray(sem), converged=np.asarray(converged),
                        level=np.asarray(level), levels_sem=sem_k, levels_err=err_k)


def ar1_sem(phi: float, sigma_noise: float, n: int) -> float:
    """Analytic standard error of the mean of n samples of the stationary AR(1) process
    x_t = phi x_{t-1} + eps_t, eps ~ N(0, sigma_noise^2):
    var(mean) = (sigma_x^2 / n) [ (1 + phi)/(1 - phi) - 2 phi (1 - phi^n) / (n (1 - phi)^2) ],
    sigma_x^2 = sigma_noise^2 / (1 - phi^2)."""
    var_x = sigma_noise ** 2 / (1.0 - phi ** 2)
    factor = (1.0 + phi) / (1.0 - phi) - 2.0 * phi * (1.0 - phi ** n) / (n * (1.0 - phi) ** 2)
    return float(np.sqrt(var_x / n * factor))
