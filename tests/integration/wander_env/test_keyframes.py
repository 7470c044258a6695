"""Keyframe frames: in-between frames made from two rendered keys and the scene's geometry
are compared with frames rendered at the same pose (exact expectations)."""

from __future__ import annotations

import math
from dataclasses import replace

import mujoco
import numpy as np
import pytest

from wander_env.camera import (
    CAMERA_NAME,
    intrinsics,
    linearise_depth,
    project,
    rotation_from_mujoco,
    rotation_homography,
)
from wander_env.dvs import DVSEmulator, DVSParams
from wander_env.entities import PAN_JOINT
from wander_env.frames.flow_bounds import view_flow_bounds_px
from wander_env.frames.keyframe_maths import View, make_keyframe, synthesize
from wander_env.mjcf import compile_scene, geom_layer_ids
from wander_env.ptu.params import PTUParams
from wander_env.renderer import CameraRenderer
from wander_env.scenes import load_scene_config

BORDER = 8  # px kept out of the comparisons (pixels entering the view)


class Rig:
    """A scene's model, renderer and posing: keys and reference frames on demand."""

    def __init__(self, scene, ptu_params: PTUParams | None = None) -> None:
        self.model = compile_scene(scene, ptu_params)
        self.data = mujoco.MjData(self.model)
        self.cam = self.model.camera(CAMERA_NAME).id
        self.pan = int(self.model.joint(PAN_JOINT).qposadr[0])
        self.renderer = CameraRenderer(self.model)
        self.lut = geom_layer_ids(self.model)
        self.dvs = DVSEmulator(128, 128, DVSParams())
        self.k = intrinsics(128, 128, float(self.model.cam_fovy[self.cam]))

    def pose(self, pan_deg: float, object_pos=None) -> View:
        self.data.qpos[self.pan] = math.radians(pan_deg)
        layers = [np.zeros(3)]
        if object_pos is not None:
            self.data.mocap_pos[0] = object_pos
            layers.append(np.asarray(object_pos, float))
        mujoco.mj_kinematics(self.model, self.data)
        mujoco.mj_camlight(self.model, self.data)
        return View(
            rotation_from_mujoco(self.data.cam_xmat[self.cam]),
            self.data.cam_xpos[self.cam].copy(),
            np.stack(layers),
        )

    def lum(self) -> np.ndarray:
        rgb = self.renderer.render(self.data)
        return self.dvs.prepare(rgb).lum.reshape(128, 128)

    def key(self, t_us: int, pan_deg: float, object_pos=None):
        view = self.pose(pan_deg, object_pos)
        lum = self.lum()
        layers, depth = self.renderer.segment_depth_current(self.lut)
        return make_keyframe(t_us, lum, view, depth, layers)

    def close(self) -> None:
        self.renderer.close()


@pytest.fixture(scope="module")
def shelf():
    rig = Rig(load_scene_config("shelf"))
    yield rig
    rig.close()


@pytest.fixture(scope="module")
def hand():
    """The hand scene with its object plain white (no texture): it moves in front of the
    room's textured wall."""
    scene = load_scene_config("hand")
    obj = replace(scene.moving_objects[0], texture=None, rgba=(1.0, 1.0, 1.0, 1.0))
    rig = Rig(replace(scene, moving_objects=(obj,)))
    yield rig
    rig.close()


def log_i(lum: np.ndarray) -> np.ndarray:
    return np.log(np.maximum(lum, 1e-2))


def test_depth_buffer_is_metres_along_the_optical_axis(shelf):
    """The linearised depth of a pixel puts its 3-D point back on that pixel, and the
    zero-near mapping's ends are the clip planes."""
    view = shelf.pose(0.0)
    shelf.renderer.update(shelf.data)
    _, depth = shelf.renderer.segment_depth_current(shelf.lut)
    assert linearise_depth(np.array([0.0]), 0.1, 10.0)[0] == pytest.approx(0.1)
    ys, xs = np.mgrid[20:110:15, 20:110:15]
    z = depth[ys, xs].reshape(-1)
    rays = np.stack([xs.reshape(-1), ys.reshape(-1), np.ones(z.size)], 1) @ np.linalg.inv(shelf.k).T
    world = view.centre + (rays * z[:, None]) @ view.rotation.T
    uv, zz = project(shelf.k, view.rotation, view.centre, world)
    assert np.abs(uv[:, 0] - xs.reshape(-1)).max() < 1e-6
    assert np.abs(uv[:, 1] - ys.reshape(-1)).max() < 1e-6
    assert np.allclose(zz, z) and 0.3 < np.median(z) < 5.0


def test_rotation_homography_maps_a_world_point_between_views(shelf):
    """K R K^-1 takes a static point's pixel in one pan to its pixel in another."""
    a = shelf.pose(0.0)
    b = shelf.pose(3.0)
    point = a.centre + a.rotation @ np.array([0.3, -0.2, 2.0])
    ua, _ = project(shelf.k, a.rotation, a.centre, point[None])
    ub, _ = project(shelf.k, b.rotation, b.centre, point[None])
    h = rotation_homography(shelf.k, b.rotation.T @ a.rotation)
    m = h @ np.array([ua[0, 0], ua[0, 1], 1.0])
    assert np.allclose(m[:2] / m[2], ub[0], atol=1e-9)
    assert ub[0, 0] - ua[0, 0] > 1.5  # panning left moves the content right


@pytest.fixture(scope="module")
def room():
    """The hand scene's room alone, every surface with its smooth blob texture: a static
    textured scene without the crisp checkers whose aliasing (MSAA 4 at 128 px) no warp of
    a rendered frame can reproduce (shelf, 1 degree pan: 0.036)."""
    scene = load_scene_config("hand")
    tex = scene.room.wall_texture
    r = replace(scene.room, floor_texture=tex, ceiling_texture=tex)
    rig = Rig(replace(scene, moving_objects=(), tables=(), static_objects=(), room=r))
    yield rig
    rig.close()


def test_pure_pan_over_a_static_scene_matches_the_rendered_frame(room):
    """Keys at pan 0 and 2 degrees (3 px of flow at the edges); the frame synthesised at
    1 degree against the frame rendered there: mean |delta log I| <= 0.02 away from the
    border (the keys' plain blend: 0.05; a key itself: 0.10)."""
    a = room.key(0, 0.0)
    b = room.key(2000, 2.0)
    view = room.pose(1.0)
    rendered = room.lum()
    bound = view_flow_bounds_px(a.view, [view], room.k, np.array([np.inf]), (128, 128))[0]
    assert bound > 1.0  # the warp path, not the plain blend
    synth = synthesize(a, b, view, 0.5, room.k)
    inner = np.s_[BORDER:-BORDER, BORDER:-BORDER]

    def err(x):
        return np.abs(log_i(x) - log_i(rendered))[inner].mean()

    assert err(synth) <= 0.02
    assert err(0.5 * a.lum + 0.5 * b.lum) > 0.04  # the warp is what makes it
    # A synthesised frame at a key's own pose is that key.
    same = synthesize(a, b, a.view, 0.0, room.k)
    assert np.array_equal(same, a.lum)


def _object_centroid(lum: np.ndarray, background: np.ndarray) -> np.ndarray:
    diff = np.abs(lum - background)
    mask = diff > 0.5 * diff.max()
    ys, xs = np.nonzero(mask)
    return np.array([xs.mean(), ys.mean()]), mask


def test_object_moving_in_front_of_a_wall_lands_where_it_is_rendered(hand):
    """The object moves 0.02 m sideways (3.4 px at 0.25 m) between keys; synthesised
    halfway, its centroid is within 0.5 px of the rendered one and its silhouette is the
    rendered one (IoU >= 0.9)."""
    p0 = np.array([0.25, 0.01, 1.0])
    shift = np.array([0.0, -0.02, 0.0])  # image right
    hand.pose(0.0, p0 + np.array([0, 0, 5.0]))  # out of view: the wall alone
    wall = hand.lum()
    a = hand.key(0, 0.0, p0)
    b = hand.key(2000, 0.0, p0 + shift)
    view = hand.pose(0.0, p0 + shift / 2)
    rendered = hand.lum()
    synth = synthesize(a, b, view, 0.5, hand.k)
    c_ren, m_ren = _object_centroid(rendered, wall)
    c_syn, m_syn = _object_centroid(synth, wall)
    assert np.abs(c_syn - c_ren).max() <= 0.5
    assert (m_ren & m_syn).sum() / (m_ren | m_syn).sum() >= 0.9
    # for scale: the keys' own centroids are 1.7 px away on either side
    c_a, _ = _object_centroid(a.lum, wall)
    assert abs(c_a[0] - c_ren[0]) > 1.2


def test_disoccluded_pixels_come_from_the_key_that_sees_them(hand):
    """Pixels the object covers in the first key but has left at the synthesised time
    (and that the second key sees as wall) take the second key's values exactly."""
    p0 = np.array([0.25, 0.01, 1.0])
    shift = np.array([0.0, -0.04, 0.0])
    a = hand.key(0, 0.0, p0)
    b = hand.key(2000, 0.0, p0 + shift)
    view = hand.pose(0.0, p0 + shift / 2)
    hand.renderer.update(hand.data)
    layers_t, _ = hand.renderer.segment_depth_current(hand.lut)
    synth = synthesize(a, b, view, 0.5, hand.k)
    revealed = (a.layers == 1) & (layers_t == 0) & (b.layers == 0)
    # keep away from the silhouette's antialiased columns
    revealed &= np.roll(revealed, 1, axis=1) & np.roll(revealed, -1, axis=1)
    assert revealed.sum() >= 30
    assert np.array_equal(synth[revealed], b.lum[revealed])
    assert np.abs(log_i(synth[revealed]) - log_i(a.lum[revealed])).mean() > 0.1


def test_same_seed_gives_identical_events_in_keyframes_mode():
    import gymnasium as gym

    import wander_env  # noqa: F401

    runs = []
    for _ in range(2):
        env = gym.make("wander/Wander-v0", scene="office", frames="keyframes")
        env.reset(seed=3)
        evs = [
            env.step(np.array([0.05 * (k == 0), 0.0], np.float32))[4]["events"] for k in range(8)
        ]
        runs.append(np.concatenate(evs))
        env.close()
    assert len(runs[0]) > 100
    assert np.array_equal(runs[0], runs[1])


def test_frames_config_is_checked():
    from wander_env.env_config import WanderConfig

    with pytest.raises(
        ValueError, match=r"^frames: expected one of .keyframes., .exact., .panorama., got "
    ):
        WanderConfig(frames="fast")
    with pytest.raises(ValueError, match=r"^keyframe_ms: 2\.5 must be a whole number"):
        WanderConfig(keyframe_ms=2.5)
    # a key every tick when the interval divides a tick (100 Hz rendering, 2 ms keys)
    assert WanderConfig(render_rate_hz=100.0, control_period_s=0.02).keyframe_us == 2000
    assert WanderConfig().frames == "keyframes"


def test_camera_offset_from_the_hinge_is_reprojected_with_depth():
    """A camera 3 cm ahead of and 5 cm above the tilt hinge translates as it pans
    (parallax): keys at pan 0 and 2 degrees, reprojected with their depth, match the
    frame rendered at 1 degree as well as the pure rotation does (<= 0.02)."""
    scene = load_scene_config("hand")
    tex = scene.room.wall_texture
    r = replace(scene.room, floor_texture=tex, ceiling_texture=tex)
    hinge = PTUParams(camera_forward_m=0.03, camera_up_m=0.05)
    rig = Rig(replace(scene, moving_objects=(), tables=(), static_objects=(), room=r), hinge)
    try:
        a = rig.key(0, 0.0)
        b = rig.key(2000, 2.0)
        view = rig.pose(1.0)
        assert np.linalg.norm(view.centre - a.view.centre) > 5e-4  # the centre moved
        rendered = rig.lum()
        synth = synthesize(a, b, view, 0.5, rig.k)
        inner = np.s_[BORDER:-BORDER, BORDER:-BORDER]
        assert np.abs(log_i(synth) - log_i(rendered))[inner].mean() <= 0.02
    finally:
        rig.close()


@pytest.mark.parametrize("parallax", [False, True])
def test_layer_boxes_hold_every_candidate(hand, parallax):
    """The moving layer's target box (the hull of its key box mapped at inverse depths
    0 and its largest) holds every pixel that can take a candidate from it: the frame
    made over the boxes equals, bit for bit, the layers' kernel run over the whole image
    with no boxes; and the boxes cover far fewer pixels than the image."""
    from wander_env.frames.keyframe_maths import (
        KeyPair,
        _static_kernel,
        _synth_kernel,
        warp_keys,
    )

    p0 = np.array([0.25, 0.01, 1.0])
    shift = np.array([0.01, -0.03, 0.005])
    a = hand.key(0, 0.0, p0)
    b = hand.key(2000, 0.4, p0 + shift)
    pair = KeyPair(a, b, hand.k)
    whole = np.array([[0, 128, 0, 128]])
    covered = []
    for w in (0.25, 0.5, 0.75):
        view = hand.pose(0.4 * w, p0 + w * shift)
        if parallax:  # the camera centre moved: every pixel through the layers' kernel
            view = View(
                view.rotation, np.add(view.centre, [0.004, -0.002, 0.003]), view.layer_positions
            )
        hinv, bvec, moving, boxes = pair.params(view)
        assert bool(moving[:, 0].any()) == parallax
        weights = np.array([1.0 - w, w])
        full = np.empty((128, 128), np.float32)
        near = int(w > 0.5)
        warped = None
        if not parallax:
            warped = warp_keys(pair._arrays[0], hinv)
            _static_kernel(full, weights, near, pair._arrays[0], warped, hinv)
            near = -1
        no_boxes = np.broadcast_to(whole, boxes.shape).copy()
        _synth_kernel(
            full, whole, weights, near, pair.kernel_args(hinv, bvec, moving, no_boxes, warped)
        )
        assert np.array_equal(pair.frame(view, w), full)
        regions = pair.regions(boxes)
        covered.append(sum(int((r[1] - r[0]) * (r[3] - r[2])) for r in regions))
    object_px = int(((a.layers == 1) | (b.layers == 1)).sum())
    assert object_px > 300
    assert all(object_px <= c <= 2 * object_px for c in covered), (object_px, covered)


def test_a_keys_layer_statistics_and_the_static_median_taken_only_for_parallax(hand):
    """Per layer: presence, box, largest and (moving layers) median inverse depth, as
    numpy takes them; the static world's median is the key's ``static_rho_median``, in the
    kernels' arguments only where the camera centre moved (elsewhere 0: its ``b`` is 0)."""
    from wander_env.frames.keyframe_maths import KeyPair

    p0 = np.array([0.25, 0.01, 1.0])
    a = hand.key(0, 0.0, p0)
    b = hand.key(2000, 0.4, p0 + np.array([0.01, -0.03, 0.005]))
    for key in (a, b):
        inv = key.inv_depth
        assert key.present.tolist() == [True, True]
        ys, xs = np.nonzero(key.layers == 1)
        assert key.boxes[1].tolist() == [ys.min(), ys.max() + 1, xs.min(), xs.max() + 1]
        assert key.rho_max.tolist() == [inv[key.layers == k].max() for k in (0, 1)]
        assert key.rho_median.tolist() == [0.0, np.median(inv[key.layers == 1])]
        assert key.static_rho_median == np.median(inv[key.layers == 0]) > 0
    pair = KeyPair(a, b, hand.k)
    view = hand.pose(0.2, p0)
    for shift, static in (([0, 0, 0], [0.0, 0.0]), ([0.004, 0, 0], [a, b])):
        moved = View(view.rotation, np.add(view.centre, shift), view.layer_positions)
        rho0 = pair.kernel_args(*pair.params(moved))[9]
        want = [k if isinstance(k, float) else k.static_rho_median for k in static]
        assert rho0[:, 0].tolist() == want


def test_flow_bounds_are_the_formula_of_the_poses():
    """view_flow_bounds_px (one compiled pair at a time) against the formula in numpy:
    1.25 x (the largest move of the image's corners and edge midpoints under the
    rotation + f (|t_xy| + |t_z| r_max / f) / near of the fastest layer); within 1e-9
    relative on random poses; exactly 0 between equal poses, inf where the centre moves."""
    from scipy.spatial.transform import Rotation

    rng = np.random.default_rng(1)
    k = intrinsics(128, 96, 80.0)
    radii = np.array([np.inf, 0.1, 0.3])

    def pose():
        rot = Rotation.from_euler("xyz", rng.normal(0, 0.02, 3)).as_matrix()
        return View(rot, np.zeros(3), np.array([[0, 0, 0], *rng.normal([0, 0, 2], 0.1, (2, 3))]))

    def formula(r, v):
        xs, ys = np.meshgrid([0.0, 63.5, 127.0], [0.0, 47.5, 95.0])
        px = np.stack([xs.ravel(), ys.ravel()], 1)
        rays = np.c_[(px[:, 0] - k[0, 2]) / k[0, 0], (px[:, 1] - k[1, 2]) / k[1, 1], np.ones(9)]
        m = rays @ (v.rotation.T @ r.rotation).T
        uv = np.c_[k[0, 0] * m[:, 0] / m[:, 2] + k[0, 2], k[1, 1] * m[:, 1] / m[:, 2] + k[1, 2]]
        rot = 1.25 * np.abs(uv - px).max()
        near = (
            np.minimum(
                r.layer_positions[1:] @ r.rotation[:, 2], v.layer_positions[1:] @ v.rotation[:, 2]
            )
            - radii[1:]
        )
        t = (v.layer_positions[1:] - r.layer_positions[1:]) @ v.rotation
        move = k[0, 0] * np.hypot(t[:, 0], t[:, 1]) + np.abs(t[:, 2]) * (np.hypot(128, 96) / 2 + 1)
        return rot + 1.25 * (move / near).max()

    ref, views = pose(), [pose() for _ in range(50)]
    got = view_flow_bounds_px(ref, views, k, radii, (96, 128))
    want = np.array([formula(ref, v) for v in views])
    assert np.allclose(got, want, rtol=1e-9, atol=0)
    refs = [pose() for _ in views]
    got = view_flow_bounds_px(refs, views, k, radii, (96, 128))
    assert np.allclose(got, [formula(r, v) for r, v in zip(refs, views, strict=True)], rtol=1e-9)
    moved = View(ref.rotation, np.add(ref.centre, [0, 0, 0.01]), ref.layer_positions)
    assert view_flow_bounds_px(ref, [ref, moved], k, radii, (96, 128)).tolist() == [0.0, np.inf]


def test_frame_params_interpolate_px_is_checked():
    from wander_env.frames.source import FrameParams

    assert FrameParams().interpolate_px == 1.0
    assert FrameParams(interpolate_px=None).interpolate_px is None
    for bad in (0.0, -1.0, "1"):
        with pytest.raises(ValueError, match=r"FrameParams\.interpolate_px"):
            FrameParams(interpolate_px=bad)
