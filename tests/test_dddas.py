"""DDDAS: HOSVD, GP surrogate, particle filter vs exact posterior, assimilation, model files."""
import json

import numpy as np
import pytest
import xarray as xr

import terradyn as td
from terradyn.dddas import GaussianPosterior, ParticleFilter, Surrogate, cross_validate, hosvd
from terradyn.dddas.filter import _nb_resample, _nb_update
from terradyn.dddas.online import Assimilation, assimilate
from terradyn.errors import InputError

THETA = np.linspace(-135.0, 135.0, 91)


def truth_forces(x, theta=THETA):
    """A smooth two-parameter family of force curves (N): amplitude and shape change with x."""
    s = np.deg2rad(theta)
    fz = (2 + x) * np.exp(-((s + 0.5) ** 2) / 0.5) - 0.3 * x * np.sin(2 * s) ** 2
    fx = 0.3 * (1 + 0.5 * x) * np.sin(s) * np.exp(-(s ** 2) / 1.2) + 0.05 * x ** 2 * np.cos(s)
    return fx, fz


def stack_for(xs):
    series = []
    for x in xs:
        fx, fz = truth_forces(x)
        series.append(td.force_series("theta", THETA, fx, fz, model="analytic", inputs={"x": float(x)}))
    return td.stack(series, {"speed": np.asarray(xs, float)})


@pytest.fixture(scope="module")
def data():
    return stack_for(np.linspace(0.2, 1.1, 10))


@pytest.fixture(scope="module")
def sur(data):
    return Surrogate(inputs=["speed"], energy=0.9999).fit(data)


# ------------------------------------------------------------------ HOSVD
def test_hosvd_full_rank_reconstructs_and_truncation_error_matches_discarded_energy():
    rng = np.random.default_rng(3)
    A = rng.standard_normal((8, 30, 2)) + np.linspace(0, 1, 30)[None, :, None]
    full = hosvd(A, ranks=(7, 16, 2), center=True)
    assert np.allclose(full.reconstruct(), A, atol=1e-10)
    errs = []
    for r in range(1, 8):
        h = hosvd(A, ranks=(r, 16, 2), center=True)
        err2 = np.sum((h.reconstruct() - A) ** 2)
        # Truncating mode 1 only is a truncated SVD of the mode-1 unfolding (Eckart-Young).
        assert err2 == pytest.approx(np.sum(h.singular[0][r:] ** 2), rel=1e-9, abs=1e-9)
        errs.append(err2)
    assert all(b < a for a, b in zip(errs, errs[1:]))


def test_hosvd_energy_picks_smallest_rank_reaching_threshold():
    rng = np.random.default_rng(0)
    A = rng.standard_normal((10, 40, 2))
    for e in (0.5, 0.9, 0.95):
        h = hosvd(A, energy=e, center=False)
        for k in range(3):
            r = h.ranks[k]
            assert h.cumvar[k][r - 1] >= e - 1e-12
            if r > 1:
                assert h.cumvar[k][r - 2] < e


def test_hosvd_rejects_identical_cases():
    with pytest.raises(InputError):
        hosvd(np.ones((5, 10, 2)))


# ------------------------------------------------------------------ GP surrogate
def test_gp_surrogate_recovers_known_function_between_training_conditions(sur):
    for x in (0.35, 0.65, 0.95):
        pred = sur.predict({"speed": x})
        fx, fz = truth_forces(x)
        assert np.sqrt(np.mean((pred.Fz.values - fz) ** 2)) < 0.01 * np.abs(fz).max()
        assert np.sqrt(np.mean((pred.Fx.values - fx) ** 2)) < 0.02 * np.abs(fx).max()
        assert pred.attrs["model"] == "dddas-surrogate" and "Fz_std" in pred
    # Uncertainty grows away from the data (extrapolation).
    inside = float(sur.predict({"speed": 0.65}).Fz_std.max())
    with pytest.warns(Warning, match="outside the training range"):  # and the user is told
        outside = float(sur.predict({"speed": 2.0}).Fz_std.max())
    assert outside > 3 * inside


def test_surrogate_scaling_keeps_the_small_component(data):
    # Fx is ~10x smaller than Fz: with RMS scaling its shape is still resolved.
    s = Surrogate(inputs=["speed"]).fit(data)
    pred = s.predict({"speed": 0.5})
    fx, _ = truth_forces(0.5)
    assert np.sqrt(np.mean((pred.Fx.values - fx) ** 2)) < 0.05 * np.abs(fx).max()


def test_model_file_round_trip_and_validation(sur, tmp_path):
    p = sur.save(tmp_path / "m.nc")
    back = Surrogate.load(p)
    a, b = sur.predict({"speed": 0.57}), back.predict({"speed": 0.57})
    for v in ("Fx", "Fz", "Fx_std", "Fz_std"):
        np.testing.assert_allclose(a[v].values, b[v].values, rtol=1e-9, atol=1e-12)
    assert json.loads(xr.open_dataset(p, engine="h5netcdf").attrs["trained_on"])["model"] == "analytic"
    ds = sur.to_dataset()
    bad = ds.copy()
    bad.attrs["format_version"] = 99
    with pytest.raises(InputError, match="version"):
        Surrogate.from_dataset(bad)
    bad = ds.copy(deep=True)
    bad["basis"].values[0, 0, 0] = np.nan
    with pytest.raises(InputError, match="NaN"):
        Surrogate.from_dataset(bad)
    with pytest.raises(InputError, match="not a terradyn surrogate"):
        Surrogate.from_dataset(xr.Dataset())


def test_surrogate_input_errors(sur, data):
    with pytest.raises(InputError):
        sur.predict({"omega": 0.3})
    with pytest.raises(InputError):
        Surrogate(inputs=["nope"]).fit(data)
    with pytest.raises(InputError):
        sur.observation_rows([200.0], "Fz")  # outside the theta grid
    with pytest.raises(InputError):
        Surrogate(components=("Fz",)).fit(data)


def test_cross_validation_beats_nearest_case_and_is_fast(data):
    cv = cross_validate(data, Surrogate(inputs=["speed"], n_restarts=0))
    assert cv["mse"].dims == ("case", "component") and cv.sizes["case"] == 10
    inner = cv["mse"].isel(case=slice(1, -1))
    assert float(inner.mean()) < 0.2 * float(cv["mse_nearest"].isel(case=slice(1, -1)).mean())
    assert cv.attrs["seconds"] < 60


# ------------------------------------------------------------------ filters
def linear_problem(D=3, n_obs=25, sigma=0.4, seed=0):
    rng = np.random.default_rng(seed)
    m0 = rng.standard_normal(D)
    P0 = np.diag(rng.uniform(0.5, 1.5, D))
    c = m0 + np.sqrt(np.diag(P0)) * rng.standard_normal(D)
    H = rng.standard_normal((n_obs, D))
    off = rng.standard_normal(n_obs)
    y = H @ c + off + sigma * rng.standard_normal(n_obs)
    return m0, P0, H, off, y, sigma


@pytest.mark.parametrize("resample", ["multinomial", "systematic"])
@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_particle_filter_matches_exact_gaussian_posterior(resample, backend):
    m0, P0, H, off, y, sigma = linear_problem()
    ex = GaussianPosterior(m0, P0)
    pf = ParticleFilter(m0, P0, n_particles=20000, resample=resample, backend=backend, rng=5)
    for k in range(len(y)):
        ex.update(H[k], off[k], y[k], sigma)
        pf.update(H[k], off[k], y[k], sigma)
    sd = np.sqrt(np.diag(ex.cov))
    assert pf.n_resamples > 0
    assert np.all(np.abs(pf.mean - ex.mean) < 0.25 * sd), (pf.mean, ex.mean, sd)
    ratio = np.sqrt(np.diag(pf.cov)) / sd
    assert np.all((ratio > 0.7) & (ratio < 1.3)), ratio


def test_exact_posterior_sequential_equals_batch():
    m0, P0, H, off, y, sigma = linear_problem(D=4, n_obs=40)
    a, b = GaussianPosterior(m0, P0), GaussianPosterior(m0, P0)
    for k in range(len(y)):
        a.update(H[k], off[k], y[k], sigma)
    b.update_many(H, off, y, sigma)
    np.testing.assert_allclose(a.mean, b.mean, rtol=1e-8, atol=1e-10)
    np.testing.assert_allclose(a.cov, b.cov, rtol=1e-7, atol=1e-12)


def test_weight_kernel_matches_float64_reference():
    rng = np.random.default_rng(1)
    pf = ParticleFilter(np.zeros(5), prior_std=np.ones(5), n_particles=4001, rng=2, ess_threshold=0.0)
    C = pf.particles
    h = rng.standard_normal(5)
    ess = pf.update(h, 0.3, 1.1, 0.7)
    lw = -0.5 * (1.1 - (C @ h + 0.3)) ** 2 / 0.49
    w = np.exp(lw - lw.max())
    assert ess == pytest.approx(w.sum() ** 2 / (w * w).sum(), rel=1e-4)
    np.testing.assert_allclose(pf.weights, w / w.sum(), rtol=2e-4, atol=1e-9)


@pytest.mark.parametrize("resample", ["multinomial", "systematic"])
def test_resampling_offspring_counts_follow_the_weights(resample):
    # Two groups of particles (values 0 and 1) with weights 0.2 / 0.8 in total.
    n = 10000
    pf = ParticleFilter(np.zeros(1), prior_std=np.ones(1), n_particles=n, resample=resample, jitter=0.0,
                        ess_threshold=0.0, rng=3)
    fracs = []
    for rep in range(5):
        pf.Ct[0, :] = np.r_[np.zeros(n // 2), np.ones(n // 2)].astype(np.float32)
        # Observation y with likelihood ratio 4 between value 1 and value 0.
        sigma = 1.0
        y = 0.5 + np.log(4.0)  # log N(y;1) - log N(y;0) = y - 1/2
        pf.update(np.ones(1), 0.0, y, sigma)
        pf.resample()
        fracs.append(float(pf.Ct[0].mean()))
    f = np.array(fracs)
    assert np.all(np.abs(f - 0.8) < (0.02 if resample == "multinomial" else 0.001)), f


def _u01_reference(i, seed):
    """The kernels' uniforms: lowbias32 hash of i + seed, top 24 bits (NumPy)."""
    x = (np.asarray(i, np.uint64) + np.uint64(seed)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    x = (x * np.uint64(0x7FEB352D)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(15)
    x = (x * np.uint64(0x846CA68B)) & np.uint64(0xFFFFFFFF)
    x ^= x >> np.uint64(16)
    return (x >> np.uint64(8)).astype(float) * 2.0 ** -24


@pytest.mark.parametrize("resample", ["multinomial", "systematic"])
def test_numba_resampling_picks_the_ancestors_of_a_search(resample):
    # The kernel finds ancestors without searching (systematic: scatter + running max;
    # multinomial: a merge in four chains split along the merge path). New particle i must
    # descend from the first particle whose cumulative weight reaches its point t_i, as
    # np.searchsorted finds it: any N (small, odd), flat, skewed and mostly-zero weights.
    rng = np.random.default_rng(7)
    for n in (2, 3, 5, 8, 9, 101, 4001):
        for kind in range(4):
            w = (rng.exponential(size=n) ** (1 + 3 * kind)).astype(np.float32)
            if kind == 3:
                w[rng.random(n) < 0.7] = np.float32(1e-30)
            pf = ParticleFilter(np.zeros(2), prior_std=np.ones(2), n_particles=n, resample=resample,
                                jitter=0.0)
            pf.Ct[0] = np.arange(n, dtype=np.float32)
            pf.Ct[1] = -pf.Ct[0]
            pf._ws[1] = w
            seed = int(rng.integers(0, 2 ** 32))
            _nb_resample(pf.Ct, pf._out, pf._ws, pf._w64, pf._wi, resample == "systematic",
                         np.uint32(seed), 0.0, np.zeros(2))
            anc = pf.Ct[0].astype(np.int64)
            np.testing.assert_array_equal(pf.Ct[1], -pf.Ct[0])  # whole columns move together
            cw = np.cumsum(w.astype(float))
            if resample == "systematic":
                t = (np.arange(n) + _u01_reference(0, seed)) * cw[-1] / n
            else:  # sorted uniforms from N + 1 exponentials (the kernel's log: ~1e-7 error)
                e = -np.log1p(-_u01_reference(np.arange(n + 1), seed))
                t = np.cumsum(e)[:n] * cw[-1] / e.sum()
            ref = np.minimum(np.searchsorted(cw, t), n - 1)
            bad = np.flatnonzero(anc != ref)
            # disagreements only where a point is within rounding of a cumulative weight
            assert all(np.min(np.abs(cw - t[i])) < 1e-5 * cw[-1] for i in bad), (n, kind, bad)
            assert len(bad) <= max(1, n // 1000)
    if resample == "multinomial":  # offspring counts over many draws: mean n w / sum(w)
        n, reps = 50, 4000
        w = np.linspace(0.1, 2.0, n)
        pf = ParticleFilter(np.zeros(1), prior_std=np.ones(1), n_particles=n, resample=resample, jitter=0.0)
        tot = np.zeros(n)
        for r in range(reps):
            pf.Ct[0] = np.arange(n, dtype=np.float32)
            pf._ws[1] = w.astype(np.float32)
            _nb_resample(pf.Ct, pf._out, pf._ws, pf._w64, pf._wi, False, np.uint32(r * 7919 + 1), 0.0,
                         np.zeros(1))
            tot += np.bincount(pf.Ct[0].astype(np.int64), minlength=n)
        expect = reps * n * w / w.sum()
        z = (tot - expect) / np.sqrt(expect)  # binomial: std <= sqrt(mean)
        assert np.abs(z).max() < 4.5 and abs(z.mean()) < 0.5, z


@pytest.mark.parametrize("resample", ["multinomial", "systematic"])
def test_numba_resampling_is_reproducible_and_the_jitter_keeps_mean_and_variance(resample):
    m0, P0, H, off, y, sigma = linear_problem(D=5, n_obs=30, sigma=0.3)
    runs = []
    for _ in range(2):
        pf = ParticleFilter(m0, P0, n_particles=3001, resample=resample, rng=11)
        for k in range(len(y)):
            pf.update(H[k], off[k], y[k], sigma)
        assert pf.n_resamples > 3
        runs.append(pf.particles)
    np.testing.assert_array_equal(runs[0], runs[1])  # same seed, same particles
    # One resampling with jitter: the jittered cloud keeps the resampled cloud's mean and
    # variance (moment-matched Liu-West kernel) and its noise is uniform.
    pf = ParticleFilter(np.zeros(3), prior_std=np.ones(3), n_particles=20000, resample=resample,
                        jitter=0.5, rng=2, ess_threshold=0.0)
    pf.update(np.array([1.0, 0.5, -0.2]), 0.0, 0.8, 0.7)
    w = pf.weights
    X = pf.particles
    mu = w @ X
    sd = np.sqrt(w @ (X - mu) ** 2)
    pf.resample()
    Y = pf.particles
    np.testing.assert_allclose(Y.mean(0), mu, atol=0.03)
    np.testing.assert_allclose(Y.std(0), sd, rtol=0.03)
    assert np.all(pf.weights == pf.weights[0])


# ------------------------------------------------------------------ assimilation
def test_assimilation_converges_to_the_truth_and_handles_missing_samples(data):
    train = data.isel(case=[0, 1, 2, 3, 5, 6, 7, 8, 9])
    s = Surrogate(inputs=["speed"]).fit(train)
    x_true = 0.62  # a condition the model did not see, observed at a wrong nominal condition
    fx, fz = truth_forces(x_true)
    rng = np.random.default_rng(4)
    sig = 0.05
    obs = xr.Dataset(coords={"theta": THETA})
    obs["Fz"] = ("theta", fz + sig * rng.standard_normal(len(THETA)))
    obs["Fx"] = ("theta", np.where(np.arange(len(THETA)) % 3 == 0, np.nan, fx + sig * rng.standard_normal(len(THETA))))
    prior = s.predict({"speed": 0.5})
    err_prior = np.mean((prior.Fz.values - fz) ** 2)
    for method in ("exact", "pf"):
        post = assimilate(s, {"speed": 0.5}, obs, obs_std=sig, method=method, prior_floor=1.0,
                          **({"rng": 1} if method == "pf" else {}))
        err_post = np.mean((post.Fz.values - fz) ** 2)
        assert err_post < 0.1 * err_prior, (method, err_post, err_prior)
        assert np.mean((post.Fx.values - fx) ** 2) < np.mean((prior.Fx.values - fx) ** 2)
        # The band (from the floored prior the filter starts from) shrinks.
        start = Assimilation(s, {"speed": 0.5}, sig, method, prior_floor=1.0).prediction()
        assert float(post.Fz_std.mean()) < 0.5 * float(start.Fz_std.mean())
        assert post.attrs["model"] == f"dddas-{method}"


def test_streaming_feed_returns_series_and_skips_missing(sur):
    a = Assimilation(sur, {"speed": 0.4}, obs_std=0.1, method="pf", n_particles=500, rng=0)
    s0 = a.prediction()
    s1 = a.feed(10.0, Fx=None, Fz=float("nan"))
    np.testing.assert_allclose(s0.Fz.values, s1.Fz.values)  # nothing observed: nothing changes
    a.feed(-40.0, Fz=float(s0.Fz.interp(theta=-40.0)) + 1.0)
    assert a.n_samples == 2
    with pytest.raises(InputError):
        a.update(10.0, Fz=float("inf"))
    with pytest.raises(InputError):
        Assimilation(sur, {"speed": 0.4}, obs_std=-1.0)


@pytest.mark.parametrize("backend", ["numba", "numpy"])
def test_jitter_floor_keeps_the_particles_from_collapsing(backend):
    m0, P0, H, off, y, sigma = linear_problem(D=2, n_obs=200, sigma=0.05)
    sd0 = np.sqrt(np.diag(P0))
    plain = ParticleFilter(m0, P0, n_particles=4000, backend=backend, rng=1)
    walk = ParticleFilter(m0, P0, n_particles=4000, backend=backend, rng=1, jitter_floor=0.05)
    for k in range(len(y)):
        plain.update(H[k], off[k], y[k], sigma)
        walk.update(H[k], off[k], y[k], sigma)
    assert walk.n_resamples > 0
    # The floor's noise (0.05 prior std) is added at each resampling: the spread stays above it.
    assert np.all(np.sqrt(np.diag(walk.cov)) > 0.03 * sd0)
    assert np.all(np.sqrt(np.diag(plain.cov)) < np.sqrt(np.diag(walk.cov)))


def test_filter_survives_an_absurd_sample():
    # A sample 1e20 noise levels away must not produce NaN weights.
    pf = ParticleFilter(np.zeros(2), prior_std=np.ones(2), n_particles=1000, rng=0)
    pf.update(np.ones(2), 0.0, 1e18, 1e-3)
    assert np.isfinite(pf.weights).all() and np.isfinite(pf.mean).all()
    with pytest.raises(InputError):
        pf.update(np.ones(2), 0.0, 1.0, 0.0)
