"""The engine against FilterPy on random models, to 1e-10."""

import numpy as np
import pytest

import aidnav

filterpy = pytest.importorskip("filterpy.kalman")

#: Agreement asked of two implementations of the same algebra in double
#: precision (the issue's acceptance limit); the values are O(1).
TOL = 1e-10


def random_model(rng, n, m):
    a = rng.normal(size=(n, n))
    F = np.eye(n) + 0.05 * a
    b = rng.normal(size=(n, n))
    Q = 1e-3 * (b @ b.T / n + np.eye(n))
    H = rng.normal(size=(m, n))
    c = rng.normal(size=(m, m))
    R = c @ c.T / m + 0.5 * np.eye(m)
    d = rng.normal(size=(n, n))
    P0 = d @ d.T / n + np.eye(n)
    x0 = rng.normal(size=n)
    return F, Q, H, R, P0, x0


def filterpy_filter(F, Q, H, R, P0, x0):
    n, m = F.shape[0], H.shape[0]
    kf = filterpy.KalmanFilter(dim_x=n, dim_z=m)
    kf.F, kf.Q, kf.H, kf.R, kf.P = F.copy(), Q.copy(), H.copy(), R.copy(), P0.copy()
    kf.x = x0.reshape(n, 1).copy()
    return kf


@pytest.mark.parametrize("n,m,seed", [(1, 1, 0), (2, 1, 1), (4, 2, 2), (9, 3, 3), (15, 6, 4), (21, 6, 5)])
def test_predict_update_match_filterpy(n, m, seed):
    rng = np.random.default_rng(seed)
    F, Q, H, R, P0, x0 = random_model(rng, n, m)
    ours = aidnav.KalmanFilter(x0, P0)
    theirs = filterpy_filter(F, Q, H, R, P0, x0)
    for _ in range(30):
        z = H @ rng.normal(size=n) + rng.normal(size=m)
        ours.predict(F, Q)
        theirs.predict()
        np.testing.assert_allclose(ours.x, theirs.x.ravel(), rtol=TOL, atol=TOL)
        np.testing.assert_allclose(ours.P, theirs.P, rtol=TOL, atol=TOL)
        rec = ours.update(z, H, R)
        theirs.update(z.reshape(m, 1))
        assert rec.outcome == "accepted"
        np.testing.assert_allclose(rec.residual, theirs.y.ravel(), rtol=TOL, atol=TOL)
        np.testing.assert_allclose(rec.S, theirs.S, rtol=TOL, atol=TOL)
        np.testing.assert_allclose(rec.gain, theirs.K, rtol=TOL, atol=TOL)
        np.testing.assert_allclose(rec.nis, theirs.mahalanobis**2, rtol=TOL)
        np.testing.assert_allclose(ours.x, theirs.x.ravel(), rtol=TOL, atol=TOL)
        np.testing.assert_allclose(ours.P, theirs.P, rtol=TOL, atol=TOL)


def test_batch_with_missing_values_matches_a_filterpy_loop():
    rng = np.random.default_rng(7)
    n, m, epochs = 6, 3, 200
    F, Q, H, R, P0, x0 = random_model(rng, n, m)
    zs = rng.normal(size=(epochs, m))
    zs[rng.random(size=(epochs, m)) < 0.2] = np.nan
    zs[10] = np.nan  # a whole epoch missing
    ours = aidnav.KalmanFilter(x0, P0).batch(zs, F, Q, H, R, covariances=True, smooth=True)
    theirs = filterpy_filter(F, Q, H, R, P0, x0)
    xs, ps, xp, pp = [], [], [], []
    for z in zs:
        theirs.predict()
        xp.append(theirs.x.ravel().copy())
        pp.append(theirs.P.copy())
        present = ~np.isnan(z)
        if present.any():
            theirs.update(z[present].reshape(-1, 1), R=R[np.ix_(present, present)], H=H[present])
        xs.append(theirs.x.ravel().copy())
        ps.append(theirs.P.copy())
    np.testing.assert_allclose(ours["x"], np.array(xs), rtol=TOL, atol=TOL)
    np.testing.assert_allclose(ours["P"], np.array(ps), rtol=TOL, atol=TOL)
    assert ours["outcome"][10] == "missing" and np.isnan(ours["nis"][10])
    assert np.isnan(ours["residual"][10]).all()
    # The RTS smoother against FilterPy's (its Fs/Qs form, same algebra).
    fs = np.array([F] * epochs)
    qs = np.array([Q] * epochs)
    xs_s, ps_s, _, _ = theirs.rts_smoother(np.array(xs).reshape(epochs, n, 1), np.array(ps), fs, qs)
    np.testing.assert_allclose(ours["x_smooth"], xs_s.reshape(epochs, n), rtol=1e-9, atol=1e-9)
    np.testing.assert_allclose(ours["P_smooth"], ps_s, rtol=1e-9, atol=1e-9)
    # The standalone smoother on the stored pass gives the batch's.
    alone = aidnav.rts_smooth(np.array(xs), np.array(ps), np.array(xp), np.array(pp), F)
    np.testing.assert_allclose(alone["x"], ours["x_smooth"], rtol=TOL, atol=TOL)


def test_policies_decide_and_say_so():
    x0, P0 = np.zeros(1), np.eye(1)
    H, R = np.eye(1), np.eye(1)
    kf = aidnav.KalmanFilter(x0, P0)
    rec = kf.update(np.array([50.0]), H, R, policy=aidnav.chi2_gate(0.999))
    assert rec.outcome == "rejected" and kf.x[0] == 0.0
    assert rec.nis == pytest.approx(50.0**2 / 2.0, rel=1e-15)
    np.testing.assert_array_equal(rec.gain, np.zeros((1, 1)))
    # Huber: R inflated by sqrt(NIS)/k — the same as a plain update with that R.
    k = 1.345
    a = aidnav.KalmanFilter(x0, P0)
    rec = a.update(np.array([10.0]), H, R, policy=aidnav.huber(k))
    assert rec.outcome == "reweighted"
    b = aidnav.KalmanFilter(x0, P0)
    b.update(np.array([10.0]), H, R * (np.sqrt(rec.nis) / k))
    np.testing.assert_allclose(a.x, b.x, rtol=1e-15)
    # The registry's schemes, by name; a recovering gate accepts after its run.
    assert set(aidnav.scheme_names()) >= {"developed", "robust", "rejection", "limiting"}
    gate = aidnav.scheme("recovering_gate", recovering_after=2)
    kf = aidnav.KalmanFilter(x0, P0)
    outcomes = [kf.update(np.array([100.0]), H, R, policy=gate).outcome for _ in range(3)]
    assert outcomes == ["rejected", "rejected", "accepted"]
    assert aidnav.scheme("developed").noise_rule == "feedback"
    limiting = aidnav.scheme("limiting")
    kf = aidnav.KalmanFilter(x0, P0)
    assert kf.update(np.array([100.0]), H, R, policy=limiting).outcome == "limited"
    with pytest.raises(ValueError, match="unknown scheme \"nope\""):
        aidnav.scheme("nope")


def test_scheme_defaults_and_ranges_are_the_engines():
    defaults = aidnav.scheme_defaults()
    assert set(defaults) == {
        "chi2_probability",
        "recovering_after",
        "huber_k",
        "anomaly_gamma",
        "adaptive_window",
        "adaptive_diagonal_rule",
    }
    # A constant not given is the engine's default, whatever the constructor.
    for policy in (aidnav.chi2_gate(), aidnav.huber(), aidnav.scheme("robust"), aidnav.Policy.huber()):
        assert policy.parameters == defaults
    # The old calls still set what they set (positional, keyword).
    assert aidnav.chi2_gate(0.99).parameters == {**defaults, "chi2_probability": 0.99}
    assert aidnav.huber(k=2.0).parameters == {**defaults, "huber_k": 2.0}
    # The new keyword: eq. 4's diagonal rule.
    gain = aidnav.scheme("adaptive_gain", adaptive_diagonal_rule="any", adaptive_window=5)
    assert gain.parameters == {**defaults, "adaptive_diagonal_rule": "any", "adaptive_window": 5}
    # Out of range: the engine's check, naming the parameter, its value and the range.
    with pytest.raises(ValueError, match=r"^huber_k = 0 is out of range: allowed 0\.1 ≤ huber_k ≤ 100$"):
        aidnav.huber(0.0)
    with pytest.raises(ValueError, match=r"^chi2_probability = 1\.5 is out of range: allowed 0 < chi2_probability < 1$"):
        aidnav.chi2_gate(1.5)
    with pytest.raises(ValueError, match=r"^recovering_after = 0 is out of range"):
        aidnav.scheme("recovering_gate", recovering_after=0)
    with pytest.raises(ValueError, match="adaptive_diagonal_rule = \"most\""):
        aidnav.scheme("adaptive_gain", adaptive_diagonal_rule="most")


def test_engine_errors_name_the_step_and_the_matrix():
    with pytest.raises(aidnav.FilterError, match="P .*not symmetric"):
        aidnav.KalmanFilter(np.zeros(2), np.array([[1.0, 0.5], [0.0, 1.0]]))
    kf = aidnav.KalmanFilter(np.zeros(2), np.eye(2))
    with pytest.raises(aidnav.FilterError, match="has shape 3×3, expected 2×2"):
        kf.predict(np.eye(3), np.eye(3))
    with pytest.raises(aidnav.FilterError, match="not positive definite"):
        kf.update(np.zeros(1), np.array([[1.0, 0.0]]), np.array([[-5.0]]))
    with pytest.raises(aidnav.FilterError, match="epoch 1"):
        kf.batch(np.array([[0.0], [np.inf]]), np.eye(2), np.eye(2), np.array([[1.0, 0.0]]), np.eye(1))
    with pytest.raises(TypeError, match="policy must be an aidnav Policy"):
        kf.update(np.zeros(1), np.array([[1.0, 0.0]]), np.eye(1), policy="chi2")
