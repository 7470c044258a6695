"""Scenes: configs, MJCF, rendering, segmentation, gratings modes and trajectories."""

from __future__ import annotations

import os

os.environ.setdefault("MUJOCO_GL", "egl")  # before mujoco is imported: headless rendering

import copy
import dataclasses
import json
import math

import cv2
import mujoco
import numpy as np
import pytest
import yaml
from locations import DATA

from wander_env.camera import CAMERA_NAME, SPECK_HFOV_DEG, focal_length_px
from wander_env.config import ConfigError
from wander_env.entities import PAN_JOINT, TILT_JOINT
from wander_env.mjcf import SceneAnimator, build_mjcf, compile_scene
from wander_env.ptu.params import PTUParams
from wander_env.renderer import CameraRenderer, project_points
from wander_env.scenes import (
    assets_dir,
    available_scenes,
    load_scene_config,
    scene_config_from_dict,
)
from wander_env.textures import TextureSpec, encode_png, make_texture
from wander_env.trajectories import (
    CircularParams,
    LinearBounceParams,
    RandomWalkParams,
    WaypointsParams,
    first_bounce_time,
    make_trajectory,
    waypoint_arrival_times,
)

SCENES = ("office", "gratings", "shelf")


def _state(name: str, t: float = 0.0, **grating_changes):
    cfg = load_scene_config(name)
    if grating_changes:
        cfg = dataclasses.replace(
            cfg, gratings=dataclasses.replace(cfg.gratings, **grating_changes)
        )
    model = compile_scene(cfg)
    data = mujoco.MjData(model)
    animator = SceneAnimator(model, cfg, np.random.default_rng(0))
    animator.apply(data, t)
    mujoco.mj_forward(model, data)
    return cfg, model, data, animator


@pytest.fixture(scope="module")
def office():
    cfg, model, data, animator = _state("office")
    with CameraRenderer(model) as cam:
        yield cfg, model, data, animator, cam


# ----------------------------------------------------------------------------------------
# Scenes load, compile and render


def test_the_three_scenes_are_available():
    assert set(SCENES) <= set(available_scenes())
    assert (assets_dir() / "scenes" / "office.yaml").is_file()


@pytest.mark.parametrize("name", SCENES)
def test_scene_compiles_and_renders_textured_frames(name):
    cfg, model, data, _ = _state(name)
    assert cfg.name == name
    assert model.camera(CAMERA_NAME).id >= 0
    assert model.vis.quality.shadowsize == 0
    assert model.vis.global_.offwidth >= 128 and model.vis.global_.offheight >= 128
    with CameraRenderer(model) as cam:
        rgb, mask = cam.render_with_mask(data)
    assert rgb.shape == (128, 128, 3) and rgb.dtype == np.uint8
    assert mask.shape == (128, 128) and mask.dtype == np.int32
    assert rgb.std() > 15.0  # textures and objects visible, not a flat image
    # every 16x16 tile has some texture (no large blank regions such as a missing wall)
    tiles = rgb.astype(float).mean(axis=2).reshape(8, 16, 8, 16).std(axis=(1, 3))
    assert (tiles > 0.5).mean() > 0.75
    assert set(np.unique(mask)) <= set(range(cfg.num_objects + 1))


def test_camera_fov_matches_the_speck():
    _, model, _, _ = _state("shelf")
    assert math.isclose(SPECK_HFOV_DEG, 112.83, abs_tol=0.01)
    assert math.isclose(model.cam_fovy[model.camera(CAMERA_NAME).id], SPECK_HFOV_DEG, rel_tol=1e-5)
    assert math.isclose(focal_length_px(128, SPECK_HFOV_DEG), 42.5, rel_tol=1e-12)


def test_office_moving_objects_are_segmented_at_25_to_50_px(office):
    _, model, data, animator, cam = office
    mask = cam.segment(data)
    centres = project_points(model, data, animator.object_positions(0.0))
    for k in (1, 2):
        ys, xs = np.nonzero(mask == k)
        assert len(xs) > 0, f"object {k} not visible at t=0"
        width = xs.max() - xs.min() + 1
        assert 25 <= width <= 50, (k, width)
        assert 25**2 * 0.6 <= len(xs) <= 50**2, (k, len(xs))
        # the mask sits where the pinhole projection puts the object's centre
        cx, cy = centres[k - 1]
        assert xs.min() < cx < xs.max() and ys.min() < cy < ys.max()
    # The ball's silhouette is an ellipse whose centre lies radially outside the
    # projection of the ball's centre: f (tan(a + r) + tan(a - r)) / 2 from the image
    # centre, a the centre's angle off the axis and r = asin(R / distance). The camera
    # is at the hinge (0, 0, 1) looking along +x.
    c = animator.object_positions(0.0)[1] - np.array([0.0, 0.0, 1.0])
    a = math.atan2(math.hypot(c[1], c[2]), c[0])
    r = math.asin(0.28 / np.linalg.norm(c))
    f = focal_length_px(128, SPECK_HFOV_DEG)
    radial = f * (math.tan(a + r) + math.tan(a - r)) / 2.0
    direction = (centres[1] - 63.5) / np.linalg.norm(centres[1] - 63.5)
    ys, xs = np.nonzero(mask == 2)
    assert np.allclose([xs.mean(), ys.mean()], 63.5 + radial * direction, atol=0.5)


def test_office_objects_move_and_masks_follow(office):
    _, model, data, animator, cam = office
    before = cam.segment(data)
    animator.apply(data, 0.5)
    mujoco.mj_forward(model, data)
    after = cam.segment(data)
    animator.apply(data, 0.0)
    mujoco.mj_forward(model, data)
    for k in (1, 2):
        assert not np.array_equal(before == k, after == k)


def test_shelf_has_no_moving_objects():
    cfg, model, data, _ = _state("shelf")
    assert cfg.moving_objects == () and model.nmocap == 0
    with CameraRenderer(model) as cam:
        assert not cam.segment(data).any()


def test_pan_and_tilt_turn_the_camera_as_the_ptu_model_says():
    _, model, data, _ = _state("shelf")
    ahead = np.array([[3.0, 0.0, 1.0]])  # on the optical axis at pan = tilt = 0
    assert np.allclose(project_points(model, data, ahead), [[63.5, 63.5]], atol=1e-6)
    data.qpos[model.joint(PAN_JOINT).qposadr[0]] = math.radians(10.0)  # pan left
    data.qpos[model.joint(TILT_JOINT).qposadr[0]] = math.radians(5.0)  # tilt up
    mujoco.mj_kinematics(model, data)
    mujoco.mj_camlight(model, data)
    x, y = project_points(model, data, ahead)[0]
    f = focal_length_px(128, SPECK_HFOV_DEG)
    assert x > 63.5 and y > 63.5  # the scene moves right and down in the image
    assert math.isclose(x - 63.5, f * math.tan(math.radians(10.0)), rel_tol=0.02)


def test_renderer_closes_cleanly():
    _, model, data, _ = _state("shelf")
    cam = CameraRenderer(model)
    cam.render(data)
    cam.close()
    cam.close()
    with pytest.raises(RuntimeError, match="CameraRenderer is closed"):
        cam.render(data)
    with pytest.raises(ValueError, match="camera"):
        CameraRenderer(model, camera="nope")


# ----------------------------------------------------------------------------------------
# Gratings modes


def _grating_frames(mode: str, times=(0.0, 0.1)):
    _, model, data, animator = _state("gratings", mode=mode, profile="sine")
    frames = []
    with CameraRenderer(model) as cam:
        for t in times:
            animator.apply(data, t)
            mujoco.mj_forward(model, data)
            rgb, mask = cam.render_with_mask(data)
            frames.append(rgb.astype(int)[..., 0])
    return frames, mask


def test_gratings_modes_move_the_right_parts():
    for mode in ("eye+object", "eye-only", "object-only"):
        (a, b), mask = _grating_frames(mode)
        patch = mask == 1
        assert 25**2 <= patch.sum() <= 50**2
        ring = ~cv2.dilate(patch.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
        bg_change = np.abs(a - b)[ring].mean()
        patch_change = np.abs(a - b)[patch].mean()
        if mode == "object-only":
            assert bg_change == 0 and patch_change > 20
        else:
            assert bg_change > 20 and patch_change > 20
        if mode == "eye-only":  # the patch shows the background grating, in phase
            rows = np.nonzero(patch.any(axis=1))[0]
            inside, outside = a[rows[len(rows) // 2]], a[5]
            assert np.abs(inside - outside).max() <= 16


# ----------------------------------------------------------------------------------------
# Config validation


def _office_dict():
    with open(assets_dir() / "scenes" / "office.yaml", encoding="utf-8") as f:
        return yaml.safe_load(f)


def _bad_kind(d):
    d["moving_objects"][1]["trajectory"]["kind"] = "zigzag"


def _unknown_key(d):
    d["moving_objects"][0]["trajectory"]["speed"] = 1.0


def _bad_mode(d):
    d["moving_objects"] = []
    d["gratings"] = {"mode": "eye-and-object"}


@pytest.mark.parametrize(
    ("mutate", "field_path", "words"),
    [
        (_bad_kind, "moving_objects[1].trajectory.kind", ("zigzag", "linear_bounce", "circular")),
        (_unknown_key, "moving_objects[0].trajectory", ("unknown", "speed", "velocity")),
        (_bad_mode, "gratings.mode", ("eye-and-object", "eye+object", "eye-only", "object-only")),
        (
            lambda d: d["moving_objects"][1]["trajectory"].pop("kind"),
            "moving_objects[1].trajectory.kind: required",
            ("'linear_bounce', 'circular', 'random_walk', 'waypoints', 'scripted')",),
        ),
        (
            lambda d: d["moving_objects"][0].__setitem__("rgba", [0.2, 2, 1, 1]),
            "moving_objects[0].rgba[1]: ",
            ("less than or equal to 1", "got 2"),
        ),
        (
            lambda d: d["moving_objects"][0]["trajectory"].__setitem__(
                "velocity", [math.nan, 0, 0]
            ),
            "moving_objects[0].trajectory.velocity[0]: ",
            ("finite", "nan"),
        ),
        (
            lambda d: d.__setitem__("tables", [{"height": 0.5, "thickness": 0.6}]),
            "tables[0].thickness: must be < height (0.5), got 0.6",
            (),
        ),
        (
            lambda d: d.__setitem__("shelves", [{"levels": [0.1, 3.0]}]),
            "shelves[0].levels: must be <= height (1.8), got (0.1, 3.0)",
            (),
        ),
        (
            lambda d: d.__setitem__("lighting", {"lights": [{"direction": [0, 0, 0]}]}),
            "lighting.lights[0].direction: must not be the zero vector",
            (),
        ),
        (
            lambda d: d.__setitem__("room", {"wall_texture": {"kind": "wood", "seed": -1}}),
            "room.wall_texture.kind: expected one of 'blobs'",
            ("got 'wood'", "room.wall_texture.seed: ", "greater than or equal to 0", "got -1"),
        ),
        (
            lambda d: d.__setitem__("camera", {"width": True, "height": 0}),
            "camera.width: ",
            ("camera.width: expected int, got True", "camera.height: ", "1, got 0"),
        ),
        (
            lambda d: d.__setitem__("camera", {"hfov_deg": 180}),
            "camera.hfov_deg: must be in (0, 180) degrees, got 180.0",
            (),
        ),
        (
            lambda d: d.update(moving_objects=[], gratings={"object_size_deg": 150}),
            "gratings.object_size_deg: must be smaller than the field of view",
            ("112.8 deg", "got 150"),
        ),
        (lambda d: d.__setitem__("gratings", {}), "moving_objects: must be empty", ()),
        (lambda d: d.__setitem__("lens", 1), "unknown key 'lens' for SceneConfig", ("camera",)),
    ],
)
def test_invalid_configs_name_the_field(mutate, field_path, words):
    d = copy.deepcopy(_office_dict())
    mutate(d)
    with pytest.raises(ValueError) as info:
        scene_config_from_dict(d)
    msg = str(info.value)
    assert msg.startswith(field_path), msg
    for w in words:
        assert w in msg, (w, msg)


def test_invalid_file_names_the_file(tmp_path):
    d = _office_dict()
    d["moving_objects"][0]["size"] = [0.2, 0.2]  # a box needs 3 extents
    path = tmp_path / "bad.yaml"
    path.write_text(yaml.safe_dump(d))
    with pytest.raises(ValueError, match=r"bad\.yaml: moving_objects\[0\]\.size"):
        load_scene_config(path)
    with pytest.raises(ValueError, match=r"available: .*office"):
        load_scene_config("no_such_scene")


def test_a_gratings_patch_of_too_many_strips_is_one_line_naming_the_file(tmp_path):
    """``object_strips: 100000000`` hung ``wander run --scene FILE`` (a geom per strip)."""
    text = (assets_dir() / "scenes" / "gratings.yaml").read_text()
    path = tmp_path / "strips.yaml"
    path.write_text(text.replace("object_strips: 128", "object_strips: 100000000"))
    with pytest.raises(ConfigError) as info:
        load_scene_config(path)
    assert str(info.value) == (
        f"{path}: gratings.object_strips: input should be less than or equal to 4096, got 100000000"
    )
    path.write_text(text.replace("object_strips: 128", "object_strips: 4096"))
    assert load_scene_config(path).gratings.object_strips == 4096


def test_shipped_scenes_load_to_the_snapshot():
    """Each shipped scene loads to the same SceneConfig as the snapshot taken in
    tests/data/scene_snapshots.json (repr: every class and exact float)."""
    with open(DATA / "scene_snapshots.json", encoding="utf-8") as f:
        snapshot = json.load(f)
    assert sorted(snapshot) == list(available_scenes())
    for name, want in snapshot.items():
        cfg = load_scene_config(name)
        assert repr(cfg) == want["repr"], name
        assert json.loads(json.dumps(dataclasses.asdict(cfg))) == want["asdict"], name


# ----------------------------------------------------------------------------------------
# Trajectories


def test_linear_bounce_stays_in_bounds_and_reverses_at_the_computed_time():
    p = LinearBounceParams(
        start=(0.5, 0.2, 1.0),
        velocity=(0.0, -0.12, 0.05),
        bounds_min=(0.5, -0.45, 0.92),
        bounds_max=(0.5, 0.45, 1.12),
    )
    traj = make_trajectory(p)
    ts = np.linspace(0.0, 60.0, 6001)
    pos = np.stack([traj.position(t) for t in ts])
    assert (pos >= np.array(p.bounds_min) - 1e-12).all()
    assert (pos <= np.array(p.bounds_max) + 1e-12).all()
    assert np.all(pos[:, 0] == 0.5)
    t_hit = first_bounce_time(0.2, -0.12, -0.45, 0.45)
    assert math.isclose(t_hit, 0.65 / 0.12)
    assert math.isclose(traj.position(t_hit)[1], -0.45, abs_tol=1e-12)
    dt = 0.01
    before, after = traj.position(t_hit - dt)[1], traj.position(t_hit + dt)[1]
    assert math.isclose(before, -0.45 + 0.12 * dt, abs_tol=1e-12)
    assert math.isclose(after, -0.45 + 0.12 * dt, abs_tol=1e-12)  # mirrored: moving back up
    assert traj.position(t_hit + 2 * dt)[1] > after
    # z hits its top at (1.12 - 1.0) / 0.05 = 2.4 s
    assert math.isclose(traj.position(2.4)[2], 1.12, abs_tol=1e-12)
    assert traj.position(2.5)[2] < 1.12


def test_circular_has_constant_radius_and_period():
    p = CircularParams(centre=(0.9, -0.2, 1.3), radius=0.22, angular_speed_rad_s=2.5, plane="yz")
    traj = make_trajectory(p)
    ts = np.linspace(0.0, 10.0, 997)
    pos = np.stack([traj.position(t) for t in ts])
    r = np.linalg.norm(pos - np.array(p.centre), axis=1)
    assert np.allclose(r, 0.22, atol=1e-12)
    assert np.allclose(pos[:, 0], 0.9)
    period = 2 * math.pi / 2.5
    assert np.allclose(traj.position(0.3), traj.position(0.3 + period), atol=1e-12)


def test_waypoints_reach_each_waypoint_at_distance_over_speed():
    pts = ((0.0, 0.0, 1.0), (1.0, 0.0, 1.0), (1.0, 0.5, 1.0), (0.0, 0.5, 1.5))
    p = WaypointsParams(points=pts, speed_m_s=0.25)
    traj = make_trajectory(p)
    arrivals = waypoint_arrival_times(np.array(pts), 0.25)
    assert np.allclose(arrivals[:3], [0.0, 4.0, 6.0])
    for t, q in zip(arrivals, pts, strict=True):
        assert np.allclose(traj.position(t), q, atol=1e-12)
    loop = arrivals[-1] + np.linalg.norm(np.subtract(pts[0], pts[-1])) / 0.25
    assert np.allclose(traj.position(loop), pts[0], atol=1e-12)  # loops back to the start
    assert np.allclose(traj.position(loop + 4.0), pts[1], atol=1e-9)
    mid = traj.position(2.0)
    assert np.allclose(mid, (0.5, 0.0, 1.0))


def test_random_walk_is_deterministic_for_a_seed_and_stays_in_bounds():
    p = RandomWalkParams(
        bounds_min=(0.5, -0.5, 0.8), bounds_max=(0.5, 0.5, 1.2), speed_m_s=0.3, turn_rate_rad_s=3.0
    )
    a = make_trajectory(p, np.random.default_rng(7))
    b = make_trajectory(p, np.random.default_rng(7))
    c = make_trajectory(p, np.random.default_rng(8))
    ts = np.linspace(0.0, 5.0, 401)
    pa = np.stack([a.position(t) for t in ts])
    pb = np.stack([b.position(t) for t in ts[::-1]])[::-1]  # any query order
    pc = np.stack([c.position(t) for t in ts])
    assert np.array_equal(pa, pb)
    assert not np.allclose(pa, pc)
    assert (pa >= np.array(p.bounds_min) - 1e-12).all()
    assert (pa <= np.array(p.bounds_max) + 1e-12).all()
    assert np.all(pa[:, 0] == 0.5)  # a zero-extent axis stays put
    fine = np.stack([a.position(t) for t in np.arange(0.0, 2.0, p.dt_s)])
    path = np.linalg.norm(np.diff(fine, axis=0), axis=1).sum()
    # speed kept: 0.3 m/s over the 399 steps of 5 ms (no chord shortened at a reflection)
    assert path == pytest.approx(0.3 * 399 * p.dt_s, abs=1e-9)
    with pytest.raises(ValueError, match="needs a numpy Generator"):
        make_trajectory(p)


# ----------------------------------------------------------------------------------------
# Textures and MJCF assets


def test_textures_are_deterministic_and_encode_to_png():
    spec = TextureSpec(kind="blobs", size_px=64, scale=8, seed=3)
    a, b = make_texture(spec), make_texture(spec)
    assert a.dtype == np.uint8 and a.shape == (64, 64, 3) and np.array_equal(a, b)
    assert not np.array_equal(a, make_texture(dataclasses.replace(spec, seed=4)))
    back = cv2.imdecode(np.frombuffer(encode_png(a), np.uint8), cv2.IMREAD_COLOR)[..., ::-1]
    assert np.array_equal(back, a)
    scene = build_mjcf(load_scene_config("office"))
    assert scene.assets and all(name in scene.xml for name in scene.assets)


def test_camera_offset_matches_the_ptu_model():
    from wander_env.ptu.mechanics import camera_position

    cfg = load_scene_config("shelf")
    model = compile_scene(cfg, PTUParams(camera_forward_m=0.05, camera_up_m=0.03))
    data = mujoco.MjData(model)
    pan, tilt = 12.0, -7.0
    data.qpos[model.joint(PAN_JOINT).qposadr[0]] = math.radians(pan)
    data.qpos[model.joint(TILT_JOINT).qposadr[0]] = math.radians(tilt)
    mujoco.mj_forward(model, data)
    cam = model.camera(CAMERA_NAME).id
    expected = np.add(cfg.ptu.position, camera_position(tilt, 0.05, 0.03, pan))
    assert np.allclose(data.cam_xpos[cam], expected, atol=1e-9)
    forward = -data.cam_xmat[cam].reshape(3, 3)[:, 2]  # the camera looks along its -z
    p, t = math.radians(pan), math.radians(tilt)
    assert np.allclose(forward, [math.cos(t) * math.cos(p), math.cos(t) * math.sin(p), math.sin(t)])


@pytest.mark.parametrize(
    ("ptu", "key", "value"),
    [
        ({"position": [0, 0, 1], "camera_forward_m": 0.03}, "camera_forward_m", "0.03"),
        ({"camera_up_m": 0}, "camera_up_m", "0"),
    ],
)
def test_a_scene_file_giving_the_hinge_offset_is_refused_naming_its_home(tmp_path, ptu, key, value):
    """The camera's offset from the hinge is the PTU's (PTUParams): a scene file that gives
    it in its ``ptu`` block, even as 0, is refused in one line naming the file, the field,
    the value and where it is given now."""
    path = tmp_path / "sc.yaml"
    path.write_text(yaml.safe_dump({"ptu": ptu}))
    want = (
        f"{path}: ptu.{key}: the camera's offset from the hinge is the PTU's, not the "
        f"scene's: give it in the env's ptu block (env.ptu.{key}, or --set "
        f"env.ptu.{key}=...), got {value}"
    )
    with pytest.raises(ConfigError) as info:
        load_scene_config(path)
    assert str(info.value) == want
    with pytest.raises(ConfigError) as info:  # a dotted key, in a mapping
        scene_config_from_dict({f"ptu.{key}": ptu[key]}, where=str(path))
    assert str(info.value) == want


def test_the_env_puts_its_camera_where_its_ptu_params_say():
    """The hinge offset reaches the compiled model from PTUParams alone (the scene holds
    only the hinge's position): the model's camera sits (forward, 0, up) from the tilt
    body, in the world at the hinge plus that offset at pan = tilt = 0, where the unit's
    own kinematics put it; the frame sources see a moving centre."""
    import gymnasium as gym

    import wander_env  # noqa: F401  (registers the env)

    hinge = PTUParams(camera_forward_m=0.05, camera_up_m=0.03)
    env = gym.make("wander/Wander-v0", scene="shelf", ptu=hinge, ground_truth=False)
    try:
        u = env.unwrapped
        assert dataclasses.asdict(u.scene.ptu) == {"position": (0.0, 0.0, 1.0)}
        cam = u.model.camera(CAMERA_NAME).id
        assert u.model.cam_pos[cam].tolist() == [0.05, 0.0, 0.03]
        data = mujoco.MjData(u.model)
        mujoco.mj_forward(u.model, data)
        assert np.allclose(data.cam_xpos[cam], [0.05, 0.0, 1.03], atol=1e-12)
        offset = np.subtract(data.cam_xpos[cam], u.scene.ptu.position)
        assert np.allclose(offset, u.ptu.camera_position_m, atol=1e-12)
        assert u.stage.camera_centre_moves()
    finally:
        env.close()
    ideal = gym.make("wander/Wander-v0", scene="shelf", ground_truth=False)
    try:
        assert not ideal.unwrapped.stage.camera_centre_moves()
    finally:
        ideal.close()


def test_grating_config_built_in_code_is_checked_by_its_annotations():
    g = load_scene_config("gratings").gratings
    assert dataclasses.replace(g, mode="eye-only").effective_speeds_deg_s() == (10.0, 10.0)
    bad = [
        ({"mode": "eye-and-object"}, "mode: expected one of 'eye+object', 'eye-only'"),
        ({"distance_m": 0.0}, "distance_m: input should be greater than 0, got 0.0"),
        ({"contrast": 1.5}, "contrast: input should be less than or equal to 1, got 1.5"),
        ({"object_strips": 1}, "object_strips: input should be greater than or equal to 2"),
        ({"object_strips": 4097}, "object_strips: input should be less than or equal to 4096"),
        ({"object_speed_deg_s": math.inf}, "object_speed_deg_s: input should be a finite"),
    ]
    for changes, message in bad:
        with pytest.raises(ValueError) as info:
            dataclasses.replace(g, **changes)
        assert str(info.value).startswith(message), (changes, str(info.value))
