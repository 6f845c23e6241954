"""Basins of the magnetic pendulum against an independent
reimplementation: scipy's DOP853 integrates every orbit of a coarse grid of
starts, and each is classified by the magnet its final position lies
nearest. reeb's labels, matched with the magnets by their fixed points'
positions, agree on at least 97 % of the cells off the basins' boundaries
(a cell whose four neighbours all carry its label in both maps). Also the
attractor table as a DataFrame."""

import numpy as np
import pytest

import reeb

MAGNETS = np.array([[1.0, 0.0], [-0.5, np.sqrt(3) / 2], [-0.5, -np.sqrt(3) / 2]])
OMEGA, D, ALPHA, T_END, N = 0.5, 0.3, 0.2, 100.0, 36

POTENTIAL = (
    "omega^2*(q1^2 + q2^2)/2 - ("
    + " + ".join(f"1/sqrt((q1 - ({float(x)!r}))^2 + (q2 - ({float(y)!r}))^2 + d^2)" for x, y in MAGNETS)
    + ")"
)

SCENE = {
    "name": "magnets",
    "model": "mechanical",
    "formula": {"dof": 2, "potential": POTENTIAL, "damping": "alpha"},
    "params": {"omega": OMEGA, "d": D, "alpha": ALPHA},
    "initial": {
        "q1": {"linspace": [-2.0, 2.0, N]},
        "q2": {"linspace": [-2.0, 2.0, N]},
        "p1": 0.0,
        "p2": 0.0,
    },
    "integrator": {"scheme": "s2", "dt": 0.01, "t_end": T_END},
    "output": {"final": ["q", "p"], "attractors": {"every": 200}},
    "run": {"precision": "f64", "backend": "cpu"},
}


def field(_t, y):
    """The whole grid as one system: y = (q1, q2, p1, p2) per orbit."""
    q1, q2, p1, p2 = y.reshape(4, -1)
    a1 = -OMEGA**2 * q1 - ALPHA * p1
    a2 = -OMEGA**2 * q2 - ALPHA * p2
    for x, z in MAGNETS:
        r3 = ((x - q1) ** 2 + (z - q2) ** 2 + D**2) ** 1.5
        a1 += (x - q1) / r3
        a2 += (z - q2) / r3
    return np.concatenate([p1, p2, a1, a2])


def nearest_magnet(q1, q2):
    d = (q1[:, None] - MAGNETS[None, :, 0]) ** 2 + (q2[:, None] - MAGNETS[None, :, 1]) ** 2
    return d.argmin(axis=1)


def interior(labels):
    """Cells whose four neighbours carry their label (grid edges excluded)."""
    c = labels[1:-1, 1:-1]
    same = (
        (labels[:-2, 1:-1] == c)
        & (labels[2:, 1:-1] == c)
        & (labels[1:-1, :-2] == c)
        & (labels[1:-1, 2:] == c)
    )
    out = np.zeros_like(labels, dtype=bool)
    out[1:-1, 1:-1] = same
    return out


def test_basins_agree_with_scipy_dop853_off_their_boundaries():
    from scipy.integrate import solve_ivp

    ds = reeb.run(SCENE)
    table = reeb.attractors(ds)
    assert list(table.kind) == ["fixed_point"] * 3
    # Each label's magnet, from the position of its fixed point.
    magnet_of = {
        label: int(nearest_magnet(np.array([row.points_q1[0]]), np.array([row.points_q2[0]]))[0])
        for label, row in table.iterrows()
    }
    ours = np.vectorize(magnet_of.get)(ds.attractor.values)

    g = np.linspace(-2.0, 2.0, N)
    q1, q2 = np.meshgrid(g, g, indexing="ij")
    y0 = np.concatenate([q1.ravel(), q2.ravel(), np.zeros(N * N), np.zeros(N * N)])
    sol = solve_ivp(field, (0.0, T_END), y0, method="DOP853", rtol=1e-9, atol=1e-9)
    assert sol.success
    end = sol.y[:, -1].reshape(4, -1)
    theirs = nearest_magnet(end[0], end[1]).reshape(N, N)

    cells = interior(ours) & interior(theirs)
    agree = (ours[cells] == theirs[cells]).mean()
    everywhere = (ours == theirs).mean()
    print(f"{cells.sum()} interior cells of {N * N}; agreement {agree:.4f} there, {everywhere:.4f} on every cell")
    assert cells.sum() >= 0.3 * N * N
    assert agree >= 0.97


def test_the_attractor_table_is_a_dataframe_with_its_fractions():
    scene = dict(SCENE, output={"final": ["q"], "attractors": True})
    scene["initial"] = dict(SCENE["initial"], q1={"linspace": [-2.0, 2.0, 8]}, q2={"linspace": [-2.0, 2.0, 8]})
    ds = reeb.run(scene)
    table = reeb.attractors(ds)
    assert table.index.name == "label"
    assert {"kind", "period", "count", "fraction", "fraction_error", "points_q1", "points_p2"} <= set(
        table.columns
    )
    assert table["count"].sum() == 64
    assert np.isclose(table["fraction"].sum(), 1.0)
    assert ds.attractor.dims == ("q1", "q2")
    assert ds.attrs["attractors"]["count"] == len(table[table.index >= 0])
    with pytest.raises(reeb.ReebError, match="no output.attractors"):
        reeb.attractors(reeb.run(dict(SCENE, output={"final": ["q"]})))
