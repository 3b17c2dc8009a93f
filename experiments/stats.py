"""Statistics over seeds, numpy only: how every claim and interval in results/ is computed.

The protocol of Agarwal et al. 2021 ("Deep RL at the edge of the statistical
precipice", the rliable library) and Henderson et al. 2018: percentile
bootstrap intervals of a mean over runs, of a difference between two
conditions (each resampled on its own), and the probability of improvement
P(X > Y).  A run is summarised by its area under the curve (its mean distance
over iterations 1..N: "learns faster") or by the iteration it converges at.
"""
from __future__ import annotations

import math

import numpy as np

RESAMPLES = 10_000           # bootstrap resamples per interval
LEVEL = 0.95                 # confidence level of every interval


def resample(x, resamples: int, rng: np.random.Generator) -> np.ndarray:
    """(resamples, n): the n runs of x drawn with replacement, `resamples` times."""
    x = np.asarray(x, float)
    return x[rng.integers(len(x), size=(resamples, len(x)))]


def percentile_interval(values) -> tuple[float, float]:
    """The central LEVEL interval of bootstrap values: their 2.5th and 97.5th percentiles."""
    tail = 100 * (1 - LEVEL) / 2
    lo, hi = np.percentile(values, [tail, 100 - tail])
    return float(lo), float(hi)


def bootstrap_ci(x, statistic=np.mean, resamples: int = RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of statistic(x) over runs (statistic takes axis=-1).

    Example: x = [0, 1] resamples to the means 0, 0.5 and 1 with probabilities
    1/4, 1/2 and 1/4, so the 95 % interval is (0, 1).
    """
    return percentile_interval(statistic(resample(x, resamples, np.random.default_rng(seed)), axis=-1))


def bootstrap_diff_ci(x, y, statistic=np.mean, resamples: int = RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of statistic(x) - statistic(y), each condition's runs resampled on its own."""
    rng = np.random.default_rng(seed)
    return percentile_interval(statistic(resample(x, resamples, rng), axis=-1)
                               - statistic(resample(y, resamples, rng), axis=-1))


def iqm(x, axis=-1):
    """The interquartile mean over runs (rliable's aggregate_iqm, scipy's trim_mean(x, 0.25)): sort,
    drop int(n / 4) runs at each end, average the rest; robust to a seed that stands apart.

    Example: x = [0, 1, 2, 3, 100] drops 0 and 100 (int(5 / 4) = 1), so the IQM is 2 (the mean 21.2).
    """
    x = np.sort(np.asarray(x, float), axis=axis)
    n = x.shape[axis]
    cut = int(0.25 * n)
    return np.take(x, range(cut, n - cut), axis=axis).mean(axis=axis)


def probability_of_improvement(x, y):
    """P(X > Y) over runs (rliable): the mean over all pairs (i, j) of 1 if x_i > y_j, 1/2 if equal,
    0 otherwise, which is the Mann-Whitney U statistic divided by n m.  Leading axes are batches.

    Example: x = [1, 2, 3], y = [2, 2]: the six pairs score 0, 0, 1/2, 1/2, 1, 1, so 0.5.
    """
    x, y = np.asarray(x, float)[..., :, None], np.asarray(y, float)[..., None, :]
    p = ((x > y) + 0.5 * (x == y)).mean((-2, -1))
    return float(p) if p.ndim == 0 else p


def probability_of_improvement_ci(x, y, resamples: int = RESAMPLES, seed: int = 0) -> tuple[float, float]:
    """Percentile bootstrap CI of P(X > Y), each condition's runs resampled on its own."""
    rng = np.random.default_rng(seed)
    return percentile_interval(probability_of_improvement(resample(x, resamples, rng), resample(y, resamples, rng)))


def area_under_curve(curve: dict, iters: int):
    """A run's mean distance over iterations 1..iters (one number for "learns faster"); None if unfinished."""
    return float(np.mean([curve[i] for i in range(1, iters + 1)])) if all(i in curve for i in range(1, iters + 1)) \
        else None


def converged_at(curve: dict, threshold: float):
    """First iteration whose distance reaches `threshold`, or None."""
    return next((i for i in sorted(curve) if curve[i] >= threshold), None)


def iterations_to_converge(curve: dict, threshold: float, iters: int) -> int:
    """`converged_at` for one run, a run that never converges counted at the cap iters + 1."""
    at = converged_at(curve, threshold)
    return iters + 1 if at is None else at


def wilson_interval(k: int, n: int) -> tuple[float, float]:
    """The 95 % Wilson score interval of a proportion k / n (Wilson 1927): unlike p +- z sqrt(p(1-p)/n)
    it stays inside [0, 1] and does not shrink to a point at k = 0 or k = n."""
    z, p = 1.959963984540054, k / n                  # z: the normal's 97.5th percentile (LEVEL = 0.95)
    centre, half = p + z * z / (2 * n), z * math.sqrt(p * (1 - p) / n + z * z / (4 * n * n))
    return (centre - half) / (1 + z * z / n), (centre + half) / (1 + z * z / n)


def chance_of_at_least(k: int, n: int, p: float) -> float:
    """P(X >= k) for X ~ Binomial(n, p): the chance that k or more of n seeds do a thing each seed
    does with probability p (e.g. 8 or more of 10 converge)."""
    return float(sum(math.comb(n, j) * p ** j * (1 - p) ** (n - j) for j in range(k, n + 1)))


def verdict(ci: tuple[float, float], margin: float | None = None) -> str:
    """"holds" / "fails" / "not settled" for a difference's CI: with no margin, the claim is that the
    difference is above 0; with a margin, that it lies within +-margin (no real effect)."""
    lo, hi = ci
    if margin is None:
        return "holds" if lo > 0 else "fails" if hi < 0 else "not settled"
    return "holds" if -margin <= lo and hi <= margin else "fails" if hi < -margin or lo > margin else "not settled"


def interval(ci) -> str:
    return f"[{ci[0]:.2f}, {ci[1]:.2f}]"
