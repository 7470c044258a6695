"""The panorama frame source: the cube map's geometry (exact), its frame against a render
at the same pose, the moving layers' visibility test, determinism and the fallback."""

from __future__ import annotations

import math

import numpy as np
import pytest

from wander_env.camera import intrinsics
from wander_env.frames.cube import FACE_ROTATIONS, cube_inverse_depth, cube_warp, pixel_rays
from wander_env.frames.keyframe_maths import View


def _face_rays(n: int) -> np.ndarray:
    """(6, n, n, 3) world directions of every face pixel's centre (unit length)."""
    a = (np.arange(n) - (n - 1) / 2) / (n / 2)
    xs, ys = np.meshgrid(a, a)
    rays = np.stack([xs, ys, np.ones_like(xs)], -1)
    d = np.einsum("fij,yxj->fyxi", FACE_ROTATIONS, rays)
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def _rotation(pan_deg: float, tilt_deg: float) -> np.ndarray:
    """World-from-camera: pan about the world's -y (OpenCV: y down), then tilt."""
    p, t = math.radians(pan_deg), math.radians(tilt_deg)
    pan = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    tilt = np.array([[1, 0, 0], [0, math.cos(t), -math.sin(t)], [0, math.sin(t), math.cos(t)]])
    return pan @ tilt


def test_face_rotations_are_rotations_along_the_six_axes() -> None:
    for i, r in enumerate(FACE_ROTATIONS):
        assert np.allclose(r @ r.T, np.eye(3)) and np.isclose(np.linalg.det(r), 1.0)
        axis = np.zeros(3)
        axis[i // 2] = 1.0 if i % 2 == 0 else -1.0
        assert np.allclose(r[:, 2], axis)


def test_a_rotation_maps_a_smooth_panorama_where_the_geometry_says() -> None:
    """Faces holding ``1 + a·d`` (d: each face pixel's world direction): the warp of any
    rotation is ``1 + a·R·ray`` at every sensor pixel, within 5e-3 (bilinear on 64-pixel
    faces, the last half pixel of a face clamped: 3.9e-3 at most measured)."""
    n, a = 64, np.array([0.3, -0.5, 0.4])
    faces = (1.0 + _face_rays(n) @ a).astype(np.float32)
    k = intrinsics(32, 32, 90.0)
    f, c = k[0, 0], k[0, 2]
    ys, xs = np.mgrid[0:32, 0:32].astype(float)
    rays = np.stack([(xs - c) / f, (ys - c) / f, np.ones_like(xs)], -1)
    out = np.empty((32, 32), np.float32)
    for pan, tilt in ((0.0, 0.0), (30.0, 10.0), (-75.0, -40.0), (170.0, 60.0)):
        rot = _rotation(pan, tilt)
        cube_warp(out, faces, rot, f, c, c, 1, True)
        d = rays @ rot.T
        want = 1.0 + (d / np.linalg.norm(d, axis=-1, keepdims=True)) @ a
        assert np.abs(out - want).max() < 5e-3


def test_a_bright_direction_lands_on_the_pixel_it_projects_to() -> None:
    """A bright spot about direction D (a Gaussian of 1 deg on the faces): after a pan of
    20 deg and a tilt of -10 deg, the brightest sensor pixel (2 x 2 rays a pixel) is the
    one nearest ``K Rᵀ D``."""
    target = np.array([0.55, -0.05, 1.0])
    target /= np.linalg.norm(target)
    cos = _face_rays(256) @ target
    faces = np.exp(-((np.degrees(np.arccos(np.clip(cos, -1, 1))) / 1.0) ** 2))
    faces = faces.astype(np.float32)
    k = intrinsics(64, 64, 90.0)
    rot = _rotation(20.0, -10.0)
    cam = rot.T @ target
    want = k[0, 0] * cam[:2] / cam[2] + k[:2, 2]
    out = np.empty((64, 64), np.float32)
    cube_warp(out, faces, rot, k[0, 0], k[0, 2], k[1, 2], 2, False)
    y, x = np.unravel_index(np.argmax(out), out.shape)
    assert 10 < want[0] < 54 and 10 < want[1] < 54
    assert (x, y) == tuple(math.floor(v + 0.5) for v in want)


def test_inverse_depth_of_a_sphere_of_distances() -> None:
    """A cube of ray distance D everywhere: inverse depth along the optical axis is
    ``|ray| / D`` at every sensor pixel."""
    dist = np.full((6, 16, 16), 2.5, np.float32)
    k = intrinsics(8, 8, 90.0)
    out = np.empty((8, 8))
    rays = pixel_rays(8, 8, k[0, 0], 3.5, 3.5)
    cube_inverse_depth(out, dist, _rotation(33.0, 5.0), *rays)
    ys, xs = np.mgrid[0:8, 0:8]
    want = np.sqrt(((xs - 3.5) / k[0, 0]) ** 2 + ((ys - 3.5) / k[0, 0]) ** 2 + 1) / 2.5
    assert np.allclose(out, want, rtol=1e-6)


def test_layers_in_view_sees_a_ball_in_front_not_behind() -> None:
    from wander_env.frames.keyframe_maths import layers_in_view

    k = intrinsics(128, 128, 90.0)
    radii = np.array([np.inf, 0.1])

    def view(pos: tuple[float, float, float]) -> View:
        return View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], pos]))

    assert layers_in_view([view((0, 0, 2.0))], k, radii, (128, 128))
    assert not layers_in_view([view((0, 0, -2.0))], k, radii, (128, 128))
    assert not layers_in_view([view((5.0, 0, 2.0))], k, radii, (128, 128))  # 68 deg off
    assert layers_in_view([view((2.05, 0, 2.0))], k, radii, (128, 128))  # its edge inside
    assert layers_in_view([view((0, 0, -2.0)), view((0, 0, 2.0))], k, radii, (128, 128))
    assert layers_in_view([view((0, 0, -2.0))], k, np.array([np.inf, np.inf]), (128, 128))


def test_a_moving_layer_is_composited_in_front_of_the_background_not_behind() -> None:
    """Two keys 10 µs apart with a square (layer 1, 1 m away, luminance 0.8) moved 4 px
    right between them over a wall (0.2): at w = 1/2 the square is drawn 2 px right of
    its first place where the background is farther (2 m) and nowhere where a static
    occluder is nearer (0.5 m); outside its box every pixel is the background's."""
    from wander_env.frames.keyframe_maths import KeyPair, layers_over, make_keyframe

    k = intrinsics(32, 32, 90.0)
    f = k[0, 0]

    def key(t: int, x0: int) -> object:
        lum = np.full((32, 32), 0.2, np.float32)
        layers = np.zeros((32, 32), np.int32)
        lum[12:20, x0 : x0 + 8], layers[12:20, x0 : x0 + 8] = 0.8, 1
        depth = np.where(layers == 1, 1.0, 2.0)
        view = View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [x0 / f, 0, 1.0]]))
        return make_keyframe(t, lum, view, depth, layers)

    a, b = key(0, 10), key(10, 14)
    pair = KeyPair(a, b, k)
    mid = View(np.eye(3), np.zeros(3), np.array([[0, 0, 0], [12 / f, 0, 1.0]]))
    hinv, bvec, moving, boxes = pair.params(mid)
    regions = pair.regions(boxes)
    bg = np.full((32, 32), 0.3, np.float32)
    for bg_depth, want_square in ((2.0, True), (0.5, False)):
        out = bg.copy()
        rho = np.full((32, 32), 1.0 / bg_depth)
        w = np.array([0.5, 0.5])
        layers_over(out, bg, rho, regions, w, pair.kernel_args(hinv, bvec, moving, boxes))
        square = np.zeros((32, 32), bool)
        square[12:20, 12:20] = True
        if want_square:
            assert np.allclose(out[square], 0.8) and np.allclose(out[~square], 0.3)
        else:
            assert np.allclose(out, 0.3)


@pytest.mark.slow
def test_still_static_world_matches_a_render_at_the_same_pose() -> None:
    """The office at reset: the panorama's background against the exact render, on the
    static world's pixels: with the headlight held along the camera's axis, median
    |Δ ln lum| <= 0.02 and mean <= 0.05 (measured 0.005 and 0.033: 64 samples a pixel
    against the render's 4, the difference at edges); with the headlight off on both,
    median 0 (mean 0.033). A headlight turned with each face instead: median 0.19."""
    from experiments.perf.panorama import background_error
    from wander_env.frames.panorama import PanoramaParams

    for headlight, median_max, mean_max in (("camera", 0.02, 0.05), ("off", 0.0, 0.05)):
        d, _ = background_error("office", headlight)
        assert d.size > 10000  # static-world pixels
        assert np.median(d) <= median_max and d.mean() <= mean_max, (headlight, d.mean())
    assert PanoramaParams().headlight == "camera"


@pytest.mark.slow
def test_same_seed_same_events_and_a_hinge_offset_falls_back_to_keyframes() -> None:
    import gymnasium as gym

    import wander_env  # noqa: F401
    from wander_env.frames.keyframes import KeyframeFrames
    from wander_env.frames.panorama import PanoramaFrames
    from wander_env.ptu.params import PTUParams

    def events(**kw: object) -> list[np.ndarray]:
        env = gym.make("wander/Wander-v0", scene="office", **kw)
        try:
            env.reset(seed=3)
            out = []
            for i in range(4):
                a = np.array([0.4, -0.2], np.float32) if i == 0 else np.zeros(2, np.float32)
                out.append(np.asarray(env.step(a)[4]["events"]))
            if kw.get("frames") == "panorama":  # a hinge offset: the keyframe source
                kind = KeyframeFrames if kw.get("ptu") else PanoramaFrames
                assert type(env.unwrapped.source) is kind
            return out
        finally:
            env.close()

    a, b = events(frames="panorama"), events(frames="panorama")
    assert all(np.array_equal(x, y) for x, y in zip(a, b, strict=True))
    assert sum(len(x) for x in a) > 0
    ptu = PTUParams(camera_forward_m=0.03, camera_up_m=0.05)
    pano = events(frames="panorama", ptu=ptu)
    keys = events(frames="keyframes", ptu=ptu)
    assert all(np.array_equal(x, y) for x, y in zip(pano, keys, strict=True))


@pytest.mark.slow
def test_no_moving_layer_in_view_no_renders_after_reset() -> None:
    """The shelf from its start gaze has no moving layer in view: a walking camera's
    steps render nothing (the panorama alone), still make events, and the camera frame
    is the background in grey."""
    import gymnasium as gym

    import wander_env  # noqa: F401

    env = gym.make("wander/Wander-v0", scene="shelf", frames="panorama", render_mode="rgb_array")
    try:
        env.reset(seed=1)
        u = env.unwrapped
        assert not u.source.with_keys
        events = 0
        for i in range(4):
            a = np.array([0.5, 0.2], np.float32) if i == 0 else np.zeros(2, np.float32)
            info = env.step(a)[4]
            assert u.renders_in_step == 0 and not u.source.with_keys
            events += len(info["events"])
            u.stage.pose(u._t_us, u.ptu.camera_pan_deg, u.ptu.camera_tilt_deg)
            assert not info["object_mask"].any() and not u.stage.object_mask().any()
        assert events > 0
        frame = u.camera_frame
        assert frame.shape == (128, 128, 3) and (frame[..., 0] == frame[..., 2]).all()
        assert env.render().ndim == 3
    finally:
        env.close()


def test_a_layer_grows_without_wrapping_round_the_image() -> None:
    """The one-pixel growth of the moving layers shifts the layer map without wrap-around:
    a layer on the left edge reaches no pixel on the right edge."""
    from wander_env.frames.keyframe_maths import _shifted

    layers = np.zeros((4, 5), np.int32)
    layers[:, 0] = 1
    assert not _shifted(layers, 0, -1, 0)[:, -1].any()
    assert (_shifted(layers, 0, 1, 0)[:, 1] == 1).all()
    assert (_shifted(layers, 1, 1, 0)[1:, 1] == 1).all() and _shifted(layers, 1, 1, 0)[0].sum() == 0


def test_panorama_params_default_to_the_measured_variant_and_refuse_bad_values() -> None:
    from wander_env.frames.panorama import PanoramaParams

    p = PanoramaParams()
    assert (p.samples, p.prefilter, p.bilinear, p.srgb, p.edge_px) == (4, True, True, True, 1)
    for bad, match in (
        ({"samples": 0}, "samples: input should be greater than or equal to 1, got 0"),
        ({"samples": 2.5}, "samples: input should be a valid integer, got 2.5"),
        ({"edge_px": 5}, "edge_px: input should be less than or equal to 4, got 5"),
        ({"headlight": "sun"}, "headlight: expected one of 'camera', 'face', 'off', got 'sun'"),
        ({"prefilter": 1}, "prefilter: input should be a valid boolean, got 1"),
    ):
        with pytest.raises(ValueError, match=match):
            PanoramaParams(**bad)


def test_a_panorama_refuses_a_moving_camera_centre_and_create_names_the_keyframes() -> None:
    """With the camera offset from the tilt hinge the panorama is wrong (parallax):
    the class refuses the stage, and ``create`` (what the registry calls) gives the
    keyframe source instead, decided once, at construction."""
    import gymnasium as gym

    import wander_env  # noqa: F401
    from wander_env.frames.keyframes import KeyframeFrames
    from wander_env.frames.panorama import PanoramaFrames
    from wander_env.frames.source import FrameParams
    from wander_env.ptu.params import PTUParams

    env = gym.make("wander/Wander-v0", scene="office", ptu=PTUParams(camera_up_m=0.05))
    try:
        u = env.unwrapped
        assert u.stage.camera_centre_moves()
        with pytest.raises(ValueError, match=r"^frames: a panorama needs a camera centre"):
            PanoramaFrames(u.stage, u.dvs, FrameParams())
        assert type(PanoramaFrames.create(u.stage, u.dvs, FrameParams())) is KeyframeFrames
    finally:
        env.close()
