"""labsupport.trajectories: each reference's velocity and acceleration are the derivatives of its
position (central differences), the circles lie where they say, and bad arguments are named."""

from __future__ import annotations

import numpy as np
import pytest

from labsupport import trajectories as tr

REFERENCES = {
    "versine": lambda t: tr.versine(t, c=0.3),
    "sinusoid": lambda t: tr.sinusoid(t, amplitude=0.7, omega=2.0),
    "circle_2d": lambda t: tr.circle_2d(t, center=(0.5, 0.2), radius=0.15, period=6.0),
    "circle_3d": lambda t: tr.circle_3d(t, center=(1.0, 0.0, 1.5), radius=0.3, normal=(1, 2, 3), frequency=0.2),
}


@pytest.mark.parametrize("name", REFERENCES)
def test_velocity_and_acceleration_are_the_derivatives(name):
    reference, h = REFERENCES[name], 1e-5
    for t in np.linspace(0.1, 3.0, 7):
        ref, before, after = reference(t), reference(t - h), reference(t + h)
        np.testing.assert_allclose((after.pos - before.pos) / (2 * h), ref.vel, atol=1e-8)
        np.testing.assert_allclose((after.vel - before.vel) / (2 * h), ref.acc, atol=1e-7)


def test_circle_3d_stays_on_its_circle_in_its_plane():
    center, normal = np.array([1.0, 0.0, 1.5]), np.array([1.0, 2.0, 3.0])
    ref = tr.circle_3d(np.linspace(0, 5, 101), center, 0.3, normal, 0.2)
    np.testing.assert_allclose(np.linalg.norm(ref.pos - center, axis=1), 0.3, rtol=1e-12)
    np.testing.assert_allclose((ref.pos - center) @ normal, 0.0, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(ref.vel, axis=1), 0.3 * 2 * np.pi * 0.2, rtol=1e-12)


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: tr.circle_2d(0.0, (0.5, 0.2, 0.0), 0.15, 6.0), r"center must have shape \(2,\)"),
        (lambda: tr.circle_2d(0.0, (0.5, 0.2), -0.15, 6.0), "radius must be positive"),
        (lambda: tr.circle_2d(0.0, (0.5, 0.2), 0.15, 0.0), "period must be positive"),
        (lambda: tr.circle_2d(0.0, (0.5, np.nan), 0.15, 6.0), "center must be finite"),
        (lambda: tr.circle_3d(0.0, (1.0, 0.0), 0.3, (0, 0, 1), 0.2), r"center must have shape \(3,\)"),
        (lambda: tr.circle_3d(0.0, (1.0, 0.0, 1.5), 0.0, (0, 0, 1), 0.2), "radius must be positive"),
        (lambda: tr.circle_3d(0.0, (1.0, 0.0, 1.5), 0.3, (0, 0, 0), 0.2), "normal must be a non-zero"),
        (lambda: tr.circle_3d(0.0, (1.0, 0.0, 1.5), 0.3, (0, 0, 1), np.inf), "frequency must be finite"),
        (lambda: tr.circle_3d(None, (1.0, 0.0, 1.5), 0.3, (0, 0, 1), 0.2), "t must be a time in seconds.*got None"),
        (lambda: tr.circle_2d(np.array([0.0, np.nan]), (0.5, 0.2), 0.15, 6.0), "t must be finite"),
        (lambda: tr.sinusoid(0.0, omega="1"), "omega must be numbers, not text"),
        (lambda: tr.versine("0", c=0.0), "t must be numbers, not text"),
    ],
)
def test_bad_circle_arguments_are_named(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_a_set_point_holds_still_in_any_dimension():
    one = tr.set_point(2.0, [0.5, -0.1, 1.2])
    assert np.array_equal(one.pos, [0.5, -0.1, 1.2]) and not one.vel.any() and not one.acc.any()
    many = tr.set_point(np.linspace(0, 1, 4), (0.3, 0.4))
    assert many.pos.shape == many.vel.shape == many.acc.shape == (4, 2)
    assert np.array_equal(many.pos, np.tile([0.3, 0.4], (4, 1)))
    for bad, said in (("x", "not text"), ([[1.0, 2.0]], "1-D"), ([1.0, np.nan], "finite")):
        with pytest.raises(ValueError, match=said):
            tr.set_point(0.0, bad)


def test_a_sampled_reference_rounds_alike_both_ways_and_refuses_times_before_its_start():
    """``at(-1.4 dt)`` returned row 0 (int() rounds -0.9 toward zero), and ``at(2.5 dt)`` gave row 3
    while calling the object at the same time gave row 2 (NumPy rounds halves to even)."""
    dt = 0.1
    ref = tr.sample(lambda t: tr.Reference(t, 0 * t, 0 * t), dt, 1.0)
    assert len(ref.pos) == 12 and ref.pos[-1] == pytest.approx(1.1)  # one step past the duration
    for t in (0.0, 0.04, 0.25, 0.35, 1.1):
        assert ref.at(t).pos == ref(np.array([t])).pos[0] == ref.pos[ref.index(t)]
    assert ref.at(-0.04).pos == 0.0  # nearest the first sample
    for t in (-0.14, 1.2, float("nan")):
        with pytest.raises(ValueError):
            ref.at(t)
    with pytest.raises(ValueError, match="some times are outside the sampled reference"):
        ref(np.array([1.0, 1.2]))  # row 12: one past the last
    still = tr.sample(lambda t: tr.Reference(t, 0 * t, 0 * t), dt, 0.0)  # no duration: t = 0 and one step
    np.testing.assert_allclose(still.pos, [0.0, dt])


def test_a_sampled_reference_called_at_a_time_that_is_not_one_says_so():
    """nan or None used to be called "outside the sampled reference"; "0.1" was read as 0.1 s."""
    from labsupport.trajectories import sample, sinusoid

    ref = sample(sinusoid, 0.01, 1.0)
    for t, words in ((float("nan"), "t must be finite"), (None, "t must be a time in seconds"), ("0.1", "not text")):
        with pytest.raises(ValueError, match=words):
            ref(t)
    np.testing.assert_allclose(ref(np.array([0.0, 0.5])).pos, sinusoid(np.array([0.0, 0.5])).pos)


def test_the_circle_basis_is_the_labs():
    """u = n × e_z / |n × e_z|, or n × e_x for a nearly vertical normal, and v = n × u: Problem 2's
    horizontal circle (normal z) starts along u = (0, 1, 0) and turns towards v = (-1, 0, 0)."""
    for normal, u, v in (
        ((0, 0, 1), (0, 1, 0), (-1, 0, 0)),
        ((0, 0, -2), (0, -1, 0), (-1, 0, 0)),
        ((1, 0, 0), (0, -1, 0), (0, 0, -1)),
        ((1, 2, 3), (2, -1, 0), (3, 6, -5)),  # tilted: u lies in the horizontal plane
        ((0, 0.3, 1), (0, 1, -0.3), (-1.09, 0, 0)),  # |n_z| > 0.9 |n|: still the e_x rule
    ):
        n = np.array(normal, float) / np.linalg.norm(normal)
        got_u, got_v = tr.circle_basis(normal)
        np.testing.assert_allclose(got_u, np.array(u) / np.linalg.norm(u), atol=1e-15)
        np.testing.assert_allclose(got_v, np.cross(n, got_u), atol=1e-15)
        np.testing.assert_allclose(np.sign(got_v), np.sign(v))


def test_a_normal_of_any_size_gives_the_same_plane():
    """A normal of 1e200 entries overflowed its norm and gave NaN; one of 1e-320 vanished."""
    u, v = tr.circle_basis([1.0, 1.0, 0.0])
    for scale in (1e200, 1e-320, 3.0):
        us, vs = tr.circle_basis(np.array([1.0, 1.0, 0.0]) * scale)
        np.testing.assert_allclose(us, u, atol=1e-15)
        np.testing.assert_allclose(vs, v, atol=1e-15)
    np.testing.assert_allclose([u @ u, v @ v, u @ v, u @ [1, 1, 0]], [1, 1, 0, 0], atol=1e-15)
