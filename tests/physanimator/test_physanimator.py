"""physlab.physanimator: flow particles (Eqs. 8–9), strokes, rigs (Eq. 10), scenes, contacts."""
import numpy as np
import pytest

from physlab import fem
from physlab import physanimator as pa
from physlab.mesh import disk_mesh, grid_mesh


def test_flow_particles_analytic_values_and_range():
    p = np.array([0.0, 0.0])
    q = np.array([[5.0, 0.0], [0.0, 10.0], [20.0, 0.0], [0.0, 0.0]])
    s, r = 2.0, 10.0
    w = pa.wind_force(p, q, (0.0, 3.0), s, r)  # Eq. (8): s (1 - |p-q|/r) d, d normalised
    np.testing.assert_allclose(w, [[0, 1.0], [0, 0], [0, 0], [0, 2.0]])
    rep = pa.repel_force(p, q, s, r)  # Eq. (9): s (q - p) / r
    np.testing.assert_allclose(rep, [[1.0, 0], [0, 0], [0, 0], [0, 0]])
    att = pa.attract_force(p, q, s, r)  # Eq. (9): s (1 - |q-p|/r) (p - q)/|p - q|
    np.testing.assert_allclose(att, [[-1.0, 0], [0, 0], [0, 0], [0, 0]])
    with pytest.raises(ValueError, match="valid kinds"):
        pa.flow_force("vortex", p, q, s, r)
    with pytest.raises(ValueError, match="range"):
        pa.wind_force(p, q, (1, 0), s, 0.0)


def test_wavy_rig_is_eq10():
    X = np.array([[1.0, 2.0]])
    for t in (0.0, 0.3, 1.7):
        np.testing.assert_allclose(pa.wavy_rig_position(X, 5.0, 3.0, (0, 2.0), t),
                                   X + 5.0 * np.sin(3.0 * t) * np.array([0, 1.0]))
    rig = pa.WavyRig(center=(0, 0), radius=1.0, amplitude=5.0, frequency=3.0, direction=(1, 0))
    disp, vel = rig.offset(0.2)
    np.testing.assert_allclose(disp, [5 * np.sin(0.6), 0])
    np.testing.assert_allclose(vel, [15 * np.cos(0.6), 0])
    with pytest.raises(ValueError, match="selects no vertex"):
        pa.FixedRig(center=(100, 100), radius=1.0).select(np.zeros((3, 2)))


def test_stroke_particles_travel_along_the_polyline():
    st = pa.EnergyStroke([[0, 0], [100, 0], [100, 100]], "wind", speed=50.0, start=1.0)
    assert st.length == pytest.approx(200)
    pos, d = st.particles(0.5)
    assert len(pos) == 0  # not started yet
    pos, d = st.particles(1.0 + 3.0)  # travelled 150 px: on the second segment
    np.testing.assert_allclose(pos, [[100, 50]])
    np.testing.assert_allclose(d, [[0, 1]])  # wind blows along the stroke's tangent
    assert len(st.particles(1.0 + 5.0)[0]) == 0  # past the end
    loop = pa.EnergyStroke([[0, 0], [100, 0]], speed=50.0, n_particles=2, loop=True)
    pos, _ = loop.particles(7.3)  # period 2 s, particles 1 s apart: ages 1.3 and 0.3 s
    np.testing.assert_allclose(np.sort(pos[:, 0]), [15.0, 65.0])
    f = st.forces(np.array([[100, 60], [0, 0]]), 4.0)
    assert f[0, 1] > 0 and np.all(f[1] == 0)
    with pytest.raises(ValueError, match="valid kinds"):
        pa.EnergyStroke([[0, 0], [1, 0]], "gust")


def ball_scene(E, stroke_strength=4e4, **kw):
    body = pa.Body(disk_mesh((0, 0), 50.0), pa.Material(E=E, nu=0.3, rho=1.0), offset=(150, 150))
    stroke = pa.EnergyStroke([[0, 150], [400, 150]], "wind", strength=stroke_strength, range=70,
                             speed=300)
    return pa.Scene([body], strokes=[stroke], size=(400, 300), **kw)


def max_strain(anim, scene):
    b = scene.bodies[0]
    Dm_inv, _ = fem.rest_shape(b.mesh.X, b.mesh.tris)
    worst = 0.0
    for x in anim.x[0]:
        F = fem.deformation_gradients(x, b.X_canvas, b.mesh.tris, Dm_inv)
        sv = np.linalg.svd(F, compute_uv=False)
        worst = max(worst, float(np.abs(sv - 1).max()))
    return worst


def test_stiffer_material_deforms_less_under_the_same_stroke():
    strains = [max_strain(pa.simulate(sc, 0.8, progress=False), sc)
               for sc in (ball_scene(E) for E in (5e4, 1e5, 2e5, 4e5))]
    assert all(a > b for a, b in zip(strains, strains[1:])), strains
    assert strains[0] > 2 * strains[-1]


def test_internal_forces_conserve_momentum_and_wavy_rig_follows_eq10():
    sc = ball_scene(1e5, stroke_strength=0.0, damping=0.0)
    sc.bodies[0].velocity = (30.0, -10.0)
    an = pa.simulate(sc, 0.5, progress=False)
    sys_ = pa.SceneSystem(sc)
    # centre of mass moves uniformly: no external force, elastic forces sum to zero
    com = np.einsum("n,fnd->fd", sys_.mass, an.x[0]) / sys_.mass.sum()
    np.testing.assert_allclose(com, com[0] + np.outer(an.t, (30.0, -10.0)), atol=1e-6)
    rig = pa.WavyRig(body=0, center=(150, 110), radius=15.0, amplitude=12.0, frequency=9.0,
                     direction=(1, 0))
    sc.rigs = [rig]
    an = pa.simulate(sc, 0.5, progress=False)
    idx = rig.select(sc.bodies[0].X_canvas)
    expect = pa.wavy_rig_position(sc.bodies[0].X_canvas[idx], 12.0, 9.0, (1, 0), an.t[:, None, None])
    np.testing.assert_allclose(an.x[0][1:, idx], expect[1:], atol=1e-9)


def test_fixed_rig_pins_and_ground_holds():
    body = pa.Body(grid_mesh(6, 6, 60.0, 60.0), pa.Material(E=1e5), offset=(100, 50))
    sc = pa.Scene([body], rigs=[pa.FixedRig(center=(100, 50), radius=1.0)], gravity=(0, 980.0),
                  size=(300, 300))
    an = pa.simulate(sc, 0.5, progress=False)
    idx = sc.rigs[0].select(body.X_canvas)
    np.testing.assert_allclose(an.x[0][:, idx], np.broadcast_to(body.X_canvas[idx], an.x[0][:, idx].shape))
    sc = pa.Scene([body], gravity=(0, 980.0), ground=200.0, size=(300, 300))
    an = pa.simulate(sc, 1.0, progress=False)
    assert an.x[0][:, :, 1].max() <= 200.0 + 1e-9
    assert an.x[0][:, :, 1].max() > 199.9  # it did reach the ground


def test_two_body_drop_does_not_interpenetrate():
    lower = pa.Body(disk_mesh((0, 0), 40.0), pa.Material(E=2e5), offset=(150, 240), name="lower")
    upper = pa.Body(disk_mesh((0, 0), 30.0), pa.Material(E=2e5), offset=(160, 120), name="upper")
    sc = pa.Scene([lower, upper], gravity=(0, 980.0), ground=285.0, walls=(0, 300), size=(300, 300))
    an = pa.simulate(sc, 1.2, progress=False)
    assert an.stats["contacts"] > 0
    worst = 0.0
    for xl, xu in zip(an.x[0], an.x[1]):  # penetration depth of each body's boundary in the other
        for xa, xb, B, mb in ((xu, xl, lower, lower.mesh), (xl, xu, upper, upper.mesh)):
            T = mb.tris
            inside = pa.collisions.points_in_triangles(xa, xb[T[:, 0]], xb[T[:, 1]], xb[T[:, 2]]).any(1)
            if inside.any():
                e = mb.boundary_edges()
                _, _, _, dist = pa.collisions.closest_points_on_segments(xa[inside], xb[e[:, 0]], xb[e[:, 1]])
                worst = max(worst, dist.max())
    assert worst < 2.0  # px, at the frames stored


def test_too_large_dt_raises_with_safe_estimate():
    sc = ball_scene(4e6)
    safe = pa.safe_time_step(sc)
    with pytest.warns(UserWarning, match="stability estimate"):
        with pytest.raises(pa.UnstableTimeStep, match="use dt <=") as info:
            pa.simulate(sc, 0.5, dt=20 * safe, progress=False)
    assert info.value.safe_dt == pytest.approx(safe)
    pa.simulate(sc, 0.05, dt=safe, progress=False)  # and the estimate itself is fine


def test_scene_json_round_trip(tmp_path):
    tex = np.zeros((20, 30, 4), np.uint8)
    tex[5:15, 5:25] = (200, 30, 30, 255)
    body = pa.Body(disk_mesh((0, 0), 30.0), pa.Material(E=3e5, nu=0.25, rho=2.0), texture=tex,
                   offset=(100.0, 80.0), velocity=(3.0, -4.0), depth=2.5, name="ball")
    other = pa.Body(grid_mesh(3, 3, 30.0, 30.0), offset=(10.0, 10.0), name="box")
    strokes = [pa.EnergyStroke(np.array([[0, 1], [50, 60]]), "repel", strength=7.0, range=33.0,
                               speed=12.0, start=0.5, n_particles=np.int64(2), loop=True,
                               direction=(0.0, 1.0))]
    rigs = [pa.WavyRig(body=0, center=(100.0, 60.0), radius=15.0, amplitude=3.0, frequency=2.0,
                       direction=(0.0, 1.0)),
            pa.FixedRig(body=1, vertices=tuple(np.array([0, 1])))]
    sc = pa.Scene([body, other], strokes=strokes, rigs=rigs, gravity=(0.0, 500.0), ground=250.0,
                  walls=(0.0, 300.0), collisions=False, restitution=0.7, friction=0.1, damping=0.3,
                  size=np.array([320, 260]))
    path = tmp_path / "scene.json"
    sc.to_json(path)
    back = pa.Scene.from_json(path)
    np.testing.assert_array_equal(back.bodies[0].texture, tex)
    assert back.bodies[1].texture is None
    import json
    assert json.loads(back.to_json()) == json.loads(sc.to_json())
    for key in ("gravity", "ground", "walls", "collisions", "restitution", "friction", "damping"):
        assert np.all(np.asarray(getattr(back, key)) == np.asarray(getattr(sc, key))), key
    assert back.strokes[0].direction == (0.0, 1.0) and back.rigs[1].vertices == (0, 1)
    a = pa.simulate(sc, 0.1, progress=False)
    b = pa.simulate(back, 0.1, progress=False)
    np.testing.assert_array_equal(a.x[0], b.x[0])


def test_implicit_euler_takes_steps_far_above_the_explicit_limit():
    sc = ball_scene(4e6)
    dt = 10 * pa.safe_time_step(sc)
    an = pa.simulate(sc, 0.4, dt=dt, fps=24, progress=False, method="implicit_euler")
    assert np.all(np.isfinite(an.x[0]))
    assert max_strain(an, sc) < 0.05  # stiff ball: small, bounded deformation
    assert np.abs(an.x[0][-1] - an.x[0][0]).max() > 1.0  # and the stroke did push it


def _two_squares(gap=-2.0, speed=100.0, dy=0.0):
    a = grid_mesh(4, 4, 20.0, 20.0)
    b = grid_mesh(4, 4, 20.0, 20.0)
    xa, xb = a.X.copy(), b.X + (20.0 + gap, dy)
    x = np.concatenate([xa, xb])
    v = np.zeros_like(x)
    v[: a.n, 0] = speed / 2
    v[a.n:, 0] = -speed / 2
    n = a.n
    bodies = [dict(idx=np.arange(n), tris=a.tris, boundary=a.boundary_vertices(), edges=a.boundary_edges()),
              dict(idx=np.arange(n, 2 * n), tris=b.tris + n, boundary=b.boundary_vertices() + n,
                   edges=b.boundary_edges() + n)]
    return x, v, np.ones(2 * n), bodies, n


def test_contact_response_conserves_momentum_without_overshoot():
    x, v, inv_m, bodies, n = _two_squares(dy=0.5)  # offset: no collinear corners
    inside_a = pa.collisions.points_in_triangles(x[:n], *(x[bodies[1]["tris"][:, k]] for k in range(3))).any(1)
    inside_b = pa.collisions.points_in_triangles(x[n:], *(x[bodies[0]["tris"][:, k]] for k in range(3))).any(1)
    ca, cb = np.flatnonzero(inside_a), n + np.flatnonzero(inside_b)  # the touching vertices
    p0 = v.sum(0)
    x_prev = x.copy()  # each square moved 2.5 px towards the other during the step
    x_prev[:n, 0] -= 2.5
    x_prev[n:, 0] += 2.5
    hits = pa.resolve_body_contacts(x, v, inv_m, bodies, restitution=0.0, friction=0.0, x_prev=x_prev)
    assert hits > 0
    np.testing.assert_allclose(v.sum(0), p0, atol=1e-9)  # equal masses: momentum = Σ v
    rel = v[ca, 0].mean() - v[cb, 0].mean()  # was +100 (approaching)
    assert -5.0 < rel < 5.0, rel  # stopped (e = 0), not bounced apart, not still approaching


@pytest.mark.parametrize("speed", [300.0, 1000.0])
def test_fast_body_does_not_tunnel_through_a_pinned_slab(speed):
    """A ball thrown at a pinned slab (faster than the ball's elastic wave speed at 1000 px/s):
    contacts push vertices back across the edge they entered by, and the slab never moves."""
    slab = pa.Body(grid_mesh(10, 2, 200.0, 20.0), pa.Material(E=2e5), offset=(50.0, 200.0))
    ball = pa.Body(disk_mesh((0, 0), 20.0), pa.Material(E=2e5), offset=(150.0, 120.0),
                   velocity=(0.0, speed))
    sc = pa.Scene([slab, ball], rigs=[pa.FixedRig(body=0, vertices=tuple(range(slab.mesh.n)))],
                  gravity=(0, 980.0), size=(300, 300), restitution=0.3)
    an = pa.simulate(sc, 0.5, progress=False)
    np.testing.assert_array_equal(an.x[0], np.broadcast_to(slab.X_canvas, an.x[0].shape))
    assert an.x[1][:, :, 1].max() <= 200.0 + 1.0  # never inside (or below) the slab
    assert an.stats["contacts"] > 0


def test_points_on_internal_edges_are_inside():
    g = grid_mesh(2, 2, 20, 20)
    inside = pa.collisions.points_in_triangles(np.array([[10.0, 10.0], [5.0, 5.0], [12.0, 10.0]]),
                                               *(g.X[g.tris[:, k]] for k in range(3)))
    assert inside.any(1).all()
