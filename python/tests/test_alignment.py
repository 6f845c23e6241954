"""SALI and GALI_k on the linear (harmonic, and damped) oscillator's map,
against a plain numpy reimplementation of their definitions: the S2 step
of q'' = −q − α q' is one matrix M (its pieces' exact flows), the
deviation vectors start as the identity's columns and follow M, are
brought to unit length at each sample, and SALI = min ‖ŵ₁ ± ŵ₂‖,
GALI_2 = the product of the singular values of [ŵ₁ ŵ₂]."""

import numpy as np

import reeb

DT, EVERY, STEPS, FRAME = 0.1, 5, 600, 10


def s2_map(alpha: float, dt: float) -> np.ndarray:
    """C(dt/2) B(dt/2) A(dt) B(dt/2) C(dt/2) on (q, p): C moves q by τp,
    B kicks p by −τq, A scales p by e^{−τα}."""
    h = dt / 2
    c = np.array([[1.0, h], [0.0, 1.0]])
    b = np.array([[1.0, 0.0], [-h, 1.0]])
    a = np.diag([1.0, np.exp(-alpha * dt)])
    return c @ b @ a @ b @ c


def definitions(alpha: float) -> tuple[np.ndarray, np.ndarray]:
    """SALI and GALI_2 at each sample (every EVERY steps)."""
    m = np.linalg.matrix_power(s2_map(alpha, DT), EVERY)
    w = np.eye(2)
    sali, gali = [], []
    for _ in range(STEPS // EVERY):
        w = m @ w
        w = w / np.linalg.norm(w, axis=0)
        a, b = w[:, 0], w[:, 1]
        sali.append(min(np.linalg.norm(a + b), np.linalg.norm(a - b)))
        gali.append(np.prod(np.linalg.svd(w, compute_uv=False)))
    return np.array(sali), np.array(gali)


def test_sali_and_gali_are_their_definitions_on_the_linear_map():
    alphas = [0.0, 0.3, 3.0]
    ds = reeb.run(
        {
            "model": "damped_oscillator",
            "params": {"alpha": alphas, "forcing_amplitude": 0.0},
            "initial": {"q": [0.5, -1.0]},
            "integrator": {"scheme": "s2", "dt": DT, "steps": STEPS},
            "output": {
                "final": ["q"],
                "trajectory": {"every": FRAME, "vars": ["q"]},
                "sali": {"every": EVERY},
                "gali": {"k": 2, "every": EVERY},
            },
            "run": {"backend": "cpu", "precision": "f64"},
        },
        progress=False,
    )
    assert ds.sali.dims == ds.gali.dims == ("alpha", "q")
    assert ds.trajectory_sali.dims == ds.trajectory_gali.dims == ("alpha", "q", "frame")
    # The sample of frame f (step f·FRAME) is number f·FRAME/EVERY.
    frames = np.arange(1, ds.sizes["frame"]) * FRAME // EVERY - 1
    for alpha in alphas:
        sali, gali = definitions(alpha)
        at = {"alpha": alpha}
        for q in ds.q.values:
            at["q"] = q
            np.testing.assert_allclose(ds.sali.sel(at), sali[-1], rtol=1e-10, atol=1e-14)
            np.testing.assert_allclose(ds.gali.sel(at), gali[-1], rtol=1e-10, atol=1e-14)
            running = ds.trajectory_sali.sel(at).values
            assert np.isnan(running[0])
            np.testing.assert_allclose(running[1:], sali[frames], rtol=1e-10, atol=1e-14)
            running = ds.trajectory_gali.sel(at).values
            np.testing.assert_allclose(running[1:], gali[frames], rtol=1e-10, atol=1e-14)
    # The overdamped map has two real eigenvalues: both vectors turn to
    # the slower one's direction and the indices go to 0 exponentially;
    # the harmonic map rotates them, and both stay of order one.
    assert ds.sali.sel(alpha=3.0).max() < 1e-8
    assert ds.sali.sel(alpha=0.0).min() > 0.1
