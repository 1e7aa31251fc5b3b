"""Terrain identification filter (issue 13): exact marginal likelihood, recovery of a known
medium, posterior consistency against a brute-force grid, rejuvenation, streaming = batch,
bad input, and the identify / forecast commands."""
import io
import json
import sys

import numpy as np
import pytest

from terradyn.cli import main
from terradyn.dddas import terrain as T
from terradyn.errors import InputError

H_CM = np.linspace(1.0, 3.25, 5)
N_THETA = 61


@pytest.fixture(scope="module")
def model():
    from terradyn.dddas import Surrogate

    surs = {}
    for m in T.MEDIA:
        ds = T.training_stack("flat", m, {"hip_height_cm": H_CM}, N_THETA)
        surs[m] = Surrogate(inputs=["hip_height_cm"], components=T.COMPONENTS, energy=0.999, n_restarts=0).fit(ds)
    return T.TerrainModel(surs, "flat", table_points=41)


def trial(model, medium="poppy CP", h=2.2, k=1.05, noise=0.05, seed=0, n=None):
    ds = T.rft_forces("flat", medium, {"hip_height_cm": h}, k, N_THETA)
    F = {c: ds[c].values for c in T.COMPONENTS}
    rng = np.random.default_rng(seed)
    chans, obs = [], {}
    for c in T.COMPONENTS:
        rms = float(np.sqrt(np.mean(F[c] ** 2)))
        sd = noise * rms
        chans.append(T.Channel(c, {c: 1.0}, sd, 0.05 * rms, T.COMPONENT_UNITS[c]))
        obs[c] = F[c] + sd * rng.standard_normal(len(F[c]))
    th = ds.theta.values
    n = n or len(th)
    return chans, [(th[i], {c: obs[c][i] for c in obs}) for i in range(n)], F


def test_marginal_likelihood_is_the_exact_gaussian_integral(model):
    """The Rao-Blackwellised log marginal likelihood of a particle equals log N(y; k0 g,
    diag(sigma^2) + g g^T / pk + sum_ch 1_ch 1_ch^T / pb_ch) computed densely."""
    chans, samples, _ = trial(model, n=25)
    f = T.TerrainFilter(model, chans, n_particles=50, ess_threshold=0.0, seed=1)
    for th, v in samples:
        f.update(th, v)
    ys, G, Bm, var = [], [], [], []
    for j, ch in enumerate(chans):
        A, res = model.channel_rows(ch)
        for th, v in samples:
            k = int(np.argmin(np.abs(model.theta - th)))
            ys.append(v[ch.name])
            var.append(ch.noise ** 2 + res[:, k] ** 2)
            G.append(A[:, k])
            Bm.append(j)
    ys, var, G, Bm = np.array(ys), np.array(var), np.array(G), np.array(Bm)
    for i in range(0, 50, 7):
        m = f.mi[i]
        g = G[:, m] @ f.Z[i]
        C = np.diag(var[:, m]) + np.outer(g, g) * f.k_std ** 2
        for j, ch in enumerate(chans):
            e = (Bm == j).astype(float)
            C += np.outer(e, e) * ch.bias_std ** 2
        r = ys - g
        _, logdet = np.linalg.slogdet(C)
        ref = -0.5 * (r @ np.linalg.solve(C, r) + logdet + len(ys) * np.log(2 * np.pi))
        assert f.logml[i] == pytest.approx(ref, abs=1e-4 * max(1.0, abs(ref)))


def test_noise_free_data_from_a_known_medium_recover_it(model):
    chans, samples, _ = trial(model, "0.3 mm glass CP", h=1.7, k=0.95, noise=0.0001)
    chans = [T.Channel(c.name, c.weights, max(c.noise, 1e-3), c.bias_std, c.units) for c in chans]
    f = T.TerrainFilter(model, chans, n_particles=3000, seed=0)
    for th, v in samples[:30]:
        f.update(th, v)
    s = f.summary()
    assert s["medium"] == "0.3 mm glass CP" and s["medium_probabilities"]["0.3 mm glass CP"] > 0.99
    z_true = 0.95 * T.ZETA["0.3 mm glass CP"]
    assert s["zeta"]["lo"] - 0.01 <= z_true <= s["zeta"]["hi"] + 0.01
    assert abs(s["conditions"]["hip_height_cm"]["mean"] - 1.7) < 0.1
    assert f.acceptance and min(f.acceptance) > 0.0  # the MH moves do move


def _grid_posterior(model, chans, samples, k_std):
    """Brute force: exact marginal likelihood on a fine hip-height grid per medium."""
    G = np.linspace(0, 1, 401)
    post = np.zeros((len(model.media), len(G)))
    f = T.TerrainFilter(model, chans, n_particles=len(G) * len(model.media), ess_threshold=0.0,
                        k_std=k_std, move_sweeps=0, seed=0)
    f.mi[:] = np.repeat(np.arange(len(model.media)), len(G))
    f.U[:, 0] = np.tile(G, len(model.media))
    T._nb_table(model.table, f.mi, f.U, f.Z)
    for th, v in samples:
        f.update(th, v)
    post = f.logml.reshape(len(model.media), len(G))
    w = np.exp(post - post.max())
    return w.sum(1) / w.sum()


@pytest.mark.parametrize("kernel", T.MOVE_KERNELS)
def test_posterior_matches_a_brute_force_grid(model, kernel):
    """Resample-move targets the right posterior: its medium probabilities agree with an exact
    grid computation on ambiguous data (few samples, 20 % noise), with either move kernel."""
    chans, samples, _ = trial(model, "poppy LP", h=2.5, k=1.0, noise=0.2, seed=3, n=18)
    ref = _grid_posterior(model, chans, samples, 0.1)
    assert 0.05 < ref.max() < 0.95  # not degenerate: the test can tell a wrong answer
    f = T.TerrainFilter(model, chans, n_particles=5000, seed=2, move_kernel=kernel)
    for th, v in samples:
        f.update(th, v)
    p = np.array(list(f.medium_probabilities().values()))
    assert f.n_resamples >= 1
    np.testing.assert_allclose(p, ref, atol=0.06)


def _check_state_after_moves(model, chans, samples, kernel, sweeps=3):
    """After resample-moves, every particle's coefficients, running sums and log marginal
    likelihood equal those of a particle placed at its (medium, condition) that assimilated
    every sample from the start (no moves): the move's sufficient-statistics shortcut
    (and, with one condition, the exact node expansion) is the full-history likelihood."""
    f = T.TerrainFilter(model, chans, n_particles=600, seed=4, move_kernel=kernel, ess_threshold=0.0)
    for th, v in samples:
        f.update(th, v)
    f.move_sweeps = sweeps
    f.resample()
    assert sum(f.acceptance) > 0.0 and len(np.unique(f.mi)) > 1
    ref = T.TerrainFilter(model, chans, n_particles=f.n, seed=0, ess_threshold=0.0, move_sweeps=0)
    order = np.argsort(f.mi, kind="stable")
    ref.mi[:] = f.mi[order]
    ref.U[:] = f.U[order]
    T._nb_table(model.table, ref.mi, ref.U, ref.Z)
    np.testing.assert_allclose(f.Z[order], ref.Z, rtol=1e-9, atol=1e-12)
    for th, v in samples:
        ref.update(th, v)
    np.testing.assert_allclose(f.S[:, :, order], ref.S, rtol=1e-7, atol=1e-9)
    np.testing.assert_allclose(f.logml[order], ref.logml, rtol=1e-7, atol=1e-4)
    np.testing.assert_allclose(f.kpost[:, order], ref.kpost, rtol=1e-7, atol=1e-12)


@pytest.mark.parametrize("kernel", T.MOVE_KERNELS)
def test_move_state_is_the_full_history_one(model, kernel):
    chans, samples, _ = trial(model, "poppy LP", h=2.5, k=1.0, noise=0.2, seed=3, n=20)
    _check_state_after_moves(model, chans, samples, kernel)


def test_move_state_is_the_full_history_one_two_conditions():
    """The same with two conditions (the foot: length and sinkage; bilinear table)."""
    from terradyn.dddas import Surrogate

    conds = {"length_cm": np.array([25.0, 30.0, 35.0]), "sinkage_cm": np.array([0.0, 0.5, 1.0])}
    media = T.MEDIA[:2]
    surs = {m: Surrogate(inputs=list(conds), components=T.COMPONENTS, energy=0.999, n_restarts=0).fit(
        T.training_stack("foot", m, conds, 21)) for m in media}
    fm = T.TerrainModel(surs, "foot", table_points=9)
    ds = T.rft_forces("foot", media[1], {"length_cm": 28.0, "sinkage_cm": 0.4}, 1.0, 21)
    rng = np.random.default_rng(0)
    chans, obs = [], {}
    for c in T.COMPONENTS:
        sd = 0.2 * float(np.sqrt(np.mean(ds[c].values ** 2)))
        chans.append(T.Channel(c, {c: 1.0}, sd, sd, T.COMPONENT_UNITS[c]))
        obs[c] = ds[c].values + sd * rng.standard_normal(21)
    samples = [(ds.theta.values[i], {c: obs[c][i] for c in obs}) for i in range(8)]
    for kernel in T.MOVE_KERNELS:
        _check_state_after_moves(fm, chans, samples, kernel)


def test_move_rejuvenates_the_particles(model):
    chans, samples, _ = trial(model, n=40)
    plain = T.TerrainFilter(model, chans, n_particles=2000, seed=0, move_sweeps=0)
    moved = T.TerrainFilter(model, chans, n_particles=2000, seed=0, move_sweeps=1)
    for th, v in samples:
        plain.update(th, v)
        moved.update(th, v)
    assert len(np.unique(moved.U)) > 5 * len(np.unique(plain.U))


def test_forecast_is_the_posterior_mean_and_beats_the_prior(model):
    chans, samples, F = trial(model, "poppy CP", h=2.0, k=1.0, n=N_THETA)
    f = T.TerrainFilter(model, chans, n_particles=2000, seed=0)
    prior = f.forecast()
    cut = int(0.4 * N_THETA)
    for th, v in samples[:cut]:
        f.update(th, v)
    post = f.forecast()
    truth = np.stack([F[c] for c in T.COMPONENTS], -1)
    e_prior = np.mean((prior[cut:] - truth[cut:]) ** 2, 0)
    e_post = np.mean((post[cut:] - truth[cut:]) ** 2, 0)
    assert (e_post < 0.2 * e_prior).all()
    # the forecast is sum_i w_i E[k]_i (A_m z_i): compare with a direct loop over particles
    w = f.weights * f.kpost[0]
    direct = sum(w[i] * np.einsum("csp,p->sc", model.A[f.mi[i]], f.Z[i]) for i in range(0, f.n))
    np.testing.assert_allclose(post, direct, rtol=1e-9, atol=1e-12)


def test_stream_equals_batch_and_cli_lines(model, tmp_path, capsys, monkeypatch):
    chans, samples, _ = trial(model, n=20)
    a = list(T.stream(T.TerrainFilter(model, chans, n_particles=1000, seed=4), samples, forecast=False))
    b = T.trace(T.TerrainFilter(model, chans, n_particles=1000, seed=4), samples)
    np.testing.assert_array_equal([[r["medium_probabilities"][m] for m in model.media] for r in a], b.p_medium.values)
    np.testing.assert_array_equal([r["zeta"]["hi"] for r in a], b.zeta_hi.values)
    # the CLI: the same samples from a file and from stdin
    monkeypatch.setattr(T.TerrainModel, "from_rft", classmethod(lambda cls, *a, **k: model))
    lines = ["theta_deg,Fx_N,Fz_N,torque_Nm"] + [",".join(repr(float(x)) for x in (th, v["Fx"], v["Fz"], v["torque"])) for th, v in samples]
    p = tmp_path / "obs.csv"
    p.write_text("\n".join(lines) + "\n")
    noise = [x for c in chans for x in ("--noise", f"{c.name}={c.noise!r}")]
    bias = [x for c in chans for x in ("--bias-std", f"{c.name}={c.bias_std!r}")]
    out = tmp_path / "trace.nc"
    assert main(["dddas", "identify", "--obs", str(p), "--particles", "1000", "--seed", "4", "-o", str(out),
                 *noise, *bias]) == 0
    capsys.readouterr()
    monkeypatch.setattr(sys, "stdin", io.StringIO("\n".join(lines) + "\n"))
    assert main(["dddas", "identify", "--obs", "-", "--stream", "--particles", "1000", "--seed", "4",
                 *noise, *bias]) == 0
    rows = [json.loads(x) for x in capsys.readouterr().out.splitlines()]
    import xarray as xr

    with xr.open_dataset(out, engine="h5netcdf") as ds:
        np.testing.assert_allclose([[r["medium_probabilities"][m] for m in model.media] for r in rows],
                                   ds.p_medium.values, rtol=1e-12)
    assert len(rows[-1]["forecast"]["Fz"]) == len(rows[-1]["forecast_theta_deg"]) > 0


def test_bad_input_is_one_line(model, tmp_path, capsys, monkeypatch):
    chans, samples, _ = trial(model, n=5)
    f = T.TerrainFilter(model, chans, n_particles=100)
    f.update(-80.0, {"Fz": 0.1})
    with pytest.raises(InputError, match="move on along the stroke"):
        f.update(-85.0, {"Fz": 0.1})
    with pytest.raises(InputError, match="stroke"):
        f.update(120.0, {"Fz": 0.1})
    with pytest.raises(InputError, match="unknown channel"):
        f.update(-70.0, {"Fy": 0.1})
    with pytest.raises(InputError, match="1e\\+06"):
        f.update(-70.0, {"Fz": 1e300})
    with pytest.raises(InputError, match="unique"):
        T.TerrainFilter(model, [T.Channel("Fz"), T.Channel("Fz")])
    with pytest.raises(InputError, match="not a number"):
        list(T.read_samples(["theta_deg,Fz_N", "-80,hello"]))
    with pytest.raises(InputError, match="no samples"):
        T.trace(T.TerrainFilter(model, chans, n_particles=10), T.read_samples(["theta_deg,Fz_N"]))
    monkeypatch.setattr(T.TerrainModel, "from_rft", classmethod(lambda cls, *a, **k: model))
    p = tmp_path / "o.csv"
    for body, what in (("theta_deg,Fz_N\n-80,1e300\n", "within"), ("theta_deg,Fz_N\n", "no samples"),
                       ("theta_deg,Fz_N\n-80,0.1\n-85,0.2\n", "move on"), ("theta,Fz_N\n-80,1\n", "theta_deg")):
        p.write_text(body)
        assert main(["dddas", "identify", "--obs", str(p), "--particles", "100"]) == 2
        err = capsys.readouterr().err.strip().splitlines()
        assert len(err) == 1 and what in err[0], err
    p.write_text("theta_deg,Fz_N\n-80,0.1\n")
    for args in (["--noise", "Fz=0.1", "--noise", "Fz=0.2"], ["--noise", "Fy=1"], ["--lever-arm-cm", "-1"],
                 ["--particles", "1000000000"]):
        assert main(["dddas", "identify", "--obs", str(p), *args]) == 2
        assert len(capsys.readouterr().err.strip().splitlines()) == 1


def test_load_cell_channel_reads_torque_over_the_arm(model):
    ch = T.Channel.load_cell(0.1, noise=0.5)
    A, _ = model.channel_rows(ch)
    j = T.COMPONENTS.index("torque")
    np.testing.assert_allclose(A, model.A[:, j] / 0.1)
    with pytest.raises(InputError):
        T.Channel.load_cell(0.0)


def test_forecast_study_small(model, monkeypatch, tmp_path):
    from terradyn.dddas import forecast as FC

    monkeypatch.setattr(T.TerrainModel, "from_rft", classmethod(lambda cls, *a, **k: model))
    monkeypatch.setattr(FC.TerrainModel, "from_rft", classmethod(lambda cls, *a, **k: model))
    monkeypatch.setattr(FC, "training_stack", lambda leg, m, c, n: T.training_stack(leg, m, {"hip_height_cm": H_CM}, n))
    ds = FC.forecast_study(tmp_path / "fc", legs=["flat"], trials_per_medium=1, particles=500, fractions=(0.3, 0.6))
    assert ds["mse"].dims == ("leg", "trial", "fraction", "estimator", "component")
    m = ds["mse"].mean("trial")
    assert (m.sel(estimator="oracle") < m.sel(estimator="prior")).all()
    assert (tmp_path / "fc" / "forecast_mse.png").stat().st_size > 1000
    s = json.loads((tmp_path / "fc" / "summary.json").read_text())
    assert set(s["legs"]["flat"]["mse_mean"]) == set(FC.METHODS)
    leg = s["legs"]["flat"]
    # the hidden truth and the diagnostics of the Bayes ceiling are kept
    assert np.isfinite(ds["true_hip_height_cm"]).all() and (ds["k_true"] > 0).all()
    assert (ds["contact_samples"].sel(fraction=0.6) >= ds["contact_samples"].sel(fraction=0.3)).all()
    conf = leg["confusion_grid"]
    assert sum(sum(r.values()) for r in conf.values()) == ds.sizes["trial"]
    correct = sum(conf[m][m] for m in conf) / ds.sizes["trial"]
    assert correct == pytest.approx(leg["medium_correct_exact_bayes_grid"])
    assert sum(b["trials"] for b in leg["identification_by_contact_samples"]) == ds.sizes["trial"]
    assert set(leg["grid_over_oracle_by_fraction"]) == {0.3, 0.6} or set(leg["grid_over_oracle_by_fraction"]) == {"0.3", "0.6"}


def test_in_contact_marks_the_samples_with_force():
    from terradyn.dddas.forecast import in_contact

    F = np.zeros((5, len(T.COMPONENTS)))
    F[3:, T.COMPONENTS.index("Fz")] = [1.0, 2.0]
    F[2, T.COMPONENTS.index("Fx")] = 0.001  # below 1 % of the maximum
    assert in_contact(F).tolist() == [False, False, False, True, True]


def test_zeta_intervals_cover_on_rft_data_with_the_default_surrogate():
    # the default surrogate (condition-mode energy 0.9999) is close enough to RFT that the
    # exact posterior's 95 % zeta intervals at 30 % of the stroke cover the truth in most RFT
    # trials of the forecast study (flat leg: 88 % over 100; with energy 0.999 the truncation
    # biased the posterior and 72 % were covered; benchmarks/dddas_model_discrepancy.py)
    from terradyn.dddas.forecast import make_trial, prior_rms, sensor_channels

    model = T.TerrainModel.from_rft("flat", seed=0)
    bias_prior = {n: 0.05 * v for n, v in prior_rms(model, sensor_channels("flat")).items()}  # as the study
    rng = np.random.default_rng(0)
    covered = []
    for t in range(100):
        tr = make_trial("flat", model, rng, T.MEDIA[t % len(T.MEDIA)])
        g = T.TerrainFilter.on_grid(model, [T.Channel(n, w, sd, bias_prior[n]) for n, w, sd in tr["channels"]],
                                    k_std=0.1)
        for i in range(int(round(0.3 * len(tr["theta"])))):
            g.update(tr["theta"][i], {n: tr["obs"][n][i] for n in tr["obs"]})
        z = g.zeta_posterior()
        zt = tr["k"] * model.zeta[model.media.index(tr["medium"])]
        covered.append(z["lo"] <= zt <= z["hi"])
    assert np.mean(covered) >= 0.83
