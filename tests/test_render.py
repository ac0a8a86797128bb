"""Preview rendering: the figure is drawn where forward kinematics puts it, the camera follows smoothly,
the video is as long as the dance with the music in it, and bad input is a one-line error."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import numpy as np
import pytest
import soundfile as sf
from PIL import Image

from dancenet_core.bvh import write_bvh
from dancenet_core.cli import main
from dancenet_core.motion import Motion
from dancenet_core.render import (
    BACKGROUND_RGB,
    Camera,
    camera_path,
    contact_sheet,
    render_frames,
    render_motion,
)
from dancenet_core.skeleton import DEFAULT_SKELETON, JOINT_INDEX

W, H = 320, 180
ROOT = np.array([0.5, DEFAULT_SKELETON.rest_pelvis_height(), -0.3])
CHECKED = ("head", "left_wrist", "right_wrist", "pelvis", "spine3", "left_knee", "right_ankle")


def _tpose_and_raised_arm(root: np.ndarray) -> Motion:
    """Frame 0: the rest T-pose; frame 1: the same with the left arm raised straight up."""
    rot = np.zeros((2, DEFAULT_SKELETON.num_joints, 3))
    rot[1, JOINT_INDEX["left_shoulder"]] = [0.0, 0.0, np.pi / 2]  # +X (the arm) turns to +Y
    return Motion(rot, np.tile(root, (2, 1)), 30.0)


def _differs(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.abs(a.astype(int) - b.astype(int)).max())


@pytest.fixture(scope="module")
def posed() -> tuple[Motion, list[Camera], list[np.ndarray], list[np.ndarray]]:
    """The two poses seen from the front-left, the dancer right of centre, and, by the same camera, the
    same poses 6 m to the side (out of view)."""
    motion = _tpose_and_raised_arm(ROOT)
    camera = Camera(eye=np.array([-0.6, 1.7, 3.6]), target=np.array([0.0, 0.9, 0.0]), width=W, height=H)
    cameras = [camera, camera]
    frames = render_frames(motion, [0, 1], W, H, cameras=cameras)
    empty = render_frames(_tpose_and_raised_arm(ROOT + [6.0, 0.0, 0.0]), [0, 1], W, H, cameras=cameras)
    return motion, cameras, frames, empty


def test_figure_is_where_fk_puts_it(posed) -> None:
    motion, cameras, frames, empty = posed
    assert frames[0].shape == (H, W, 3)
    assert frames[0].dtype == np.uint8
    pos = motion.positions()
    for f in (0, 1):
        for name in CHECKED:
            x, y = cameras[f].project(pos[f, JOINT_INDEX[name]]).astype(int)
            assert 0 <= x < W, name
            assert 0 <= y < H, name
            # the figure covers the joint: the picture there is not what the floor or sky would show
            assert _differs(frames[f][y, x], empty[f][y, x]) > 40, (f, name)
    assert tuple(frames[0][1, 1]) == BACKGROUND_RGB  # top-left corner: sky, far from the figure
    assert _differs(empty[0], empty[1]) <= 2  # nothing of the figure leaks into the empty view


def test_raised_arm_moves_the_pixels(posed) -> None:
    motion, cameras, frames, empty = posed
    wrist = motion.positions()[:, JOINT_INDEX["left_wrist"]]
    x0, y0 = cameras[0].project(wrist[0]).astype(int)
    x1, y1 = cameras[1].project(wrist[1]).astype(int)
    assert y1 < y0 - 20
    assert abs(x1 - x0) > 10  # up and in: projection agrees with the pose
    assert _differs(frames[1][y1, x1], empty[1][y1, x1]) > 40  # the arm is now up here...
    assert _differs(frames[0][y1, x1], empty[0][y1, x1]) <= 6  # ...where the T-pose left empty space
    assert _differs(frames[1][y0, x0], empty[1][y0, x0]) <= 6  # and the T-pose's wrist place is empty


def test_camera_follows_smoothly() -> None:
    fps, n = 30.0, 300
    rng = np.random.default_rng(0)
    root = np.zeros((n, 3))
    root[:, 0] = np.linspace(0.0, 3.0, n) + rng.normal(0.0, 0.03, n)  # travel 3 m with 3 cm of jitter
    root[:, 1] = DEFAULT_SKELETON.rest_pelvis_height()
    motion = Motion(np.zeros((n, DEFAULT_SKELETON.num_joints, 3)), root, fps)
    targets = np.array([c.target for c in camera_path(motion, W, H)])
    eyes = np.array([c.eye for c in camera_path(motion, W, H)])
    assert np.allclose(eyes - targets, eyes[0] - targets[0])  # fixed direction and distance
    centre = camera_path(motion[:1], W, H)[0].project(root[0] + DEFAULT_SKELETON.offsets[0])
    assert np.allclose(centre, [W / 2, H / 2])  # a still dancer's root is in the middle of the picture
    inner = slice(30, -30)  # away from the ends, where the filter holds the path
    assert np.abs(targets[inner, 0] - np.linspace(0.0, 3.0, n)[inner]).max() < 0.02  # follows, no lag
    jerk = lambda x: np.abs(np.diff(x, 2)).mean()  # noqa: E731
    assert jerk(targets[:, 0]) < jerk(root[:, 0]) / 50  # jitter filtered out


def _probe(path: Path) -> dict[str, dict]:
    out = subprocess.run(
        ["ffprobe", "-v", "error", "-count_frames", "-show_entries",
         "stream=codec_type,duration,nb_read_frames,r_frame_rate", "-of", "json", str(path)],
        capture_output=True, text=True, check=True).stdout
    return {s["codec_type"]: s for s in json.loads(out)["streams"]}


def _dance(frames: int, fps: float) -> Motion:
    t = np.arange(frames)[:, None] / fps
    rot = np.zeros((frames, DEFAULT_SKELETON.num_joints, 3))
    rot[:, JOINT_INDEX["left_shoulder"], 2] = 0.8 * np.sin(2 * np.pi * t[:, 0])
    root = np.column_stack([0.3 * np.sin(t[:, 0]), np.full(frames, ROOT[1]), np.zeros(frames)])
    return Motion(rot, root, fps)


@pytest.mark.parametrize("song_s", [3.0, 1.0])  # music longer than the dance (cut), shorter (padded)
def test_video_length_matches_the_dance(tmp_path: Path, song_s: float) -> None:
    fps, frames = 24.0, 36
    sr = 44100
    song = tmp_path / "song.wav"
    sf.write(song, 0.3 * np.sin(2 * np.pi * 440 * np.arange(int(song_s * sr)) / sr), sr)
    out = render_motion(_dance(frames, fps), tmp_path / "dance.mp4", audio=song, width=160, height=96)
    streams = _probe(out)
    video, audio = streams["video"], streams["audio"]
    assert int(video["nb_read_frames"]) == frames
    assert video["r_frame_rate"] == "24/1"
    assert abs(float(video["duration"]) - frames / fps) < 1 / fps
    assert abs(float(audio["duration"]) - frames / fps) < 1 / fps
    assert not list(tmp_path.glob(".*partial"))


def test_cli_render_video_frames_and_sheet(tmp_path: Path) -> None:
    motion_path = tmp_path / "dance.npz"
    _dance(20, 20.0).save(motion_path)
    video, stills, sheet = tmp_path / "v.mp4", tmp_path / "frames", tmp_path / "sheet.png"
    args = ["render", str(motion_path), "-o", str(video), "--frames", str(stills), "--sheet", str(sheet),
            "--width", "160", "--height", "96", "--fps", "10"]
    assert main(args) == 0
    assert int(_probe(video)["video"]["nb_read_frames"]) == 10  # resampled to --fps
    pngs = sorted(stills.glob("frame_*.png"))
    assert len(pngs) == 10
    assert Image.open(pngs[0]).size == (160, 96)
    assert Image.open(sheet).size == (4 * 80, 3 * 48)  # 4x3 cells, each half the video size


def test_cli_reads_bvh(tmp_path: Path) -> None:
    bvh, sheet = tmp_path / "dance.bvh", tmp_path / "sheet.png"
    write_bvh(bvh, _dance(12, 12.0))
    assert main(["render", str(bvh), "--sheet", str(sheet), "--width", "64", "--height", "32"]) == 0
    assert Image.open(sheet).size == (4 * 32, 3 * 16)


def test_cli_bad_input_is_one_line(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    not_motion = tmp_path / "notes.npz"
    not_motion.write_text("not a motion")
    text = tmp_path / "notes.txt"
    text.write_text("hello")
    out = str(tmp_path / "v.mp4")
    for argv in (["render", str(tmp_path / "missing.npz"), "-o", out],
                 ["render", str(not_motion), "-o", out],
                 ["render", str(text), "-o", out],
                 ["render", str(not_motion)]):
        assert main(argv) == 2, argv
        err = capsys.readouterr().err
        assert err.startswith("dancenet: error: "), err
        assert err.count("\n") == 1, err
    assert not Path(out).exists()


def test_worker_processes_draw_the_same_frames() -> None:
    """Two worker processes, each with its own OpenGL context, give the frames one process draws, in
    order (a dance long enough for the parallel path, drawn small to stay quick)."""
    from dancenet_core.render import frames

    n = frames._PARALLEL_MIN_FRAMES + 7  # a last chunk shorter than the others
    rot = np.zeros((n, DEFAULT_SKELETON.num_joints, 3))
    rot[:, JOINT_INDEX["left_shoulder"], 2] = np.linspace(0.0, np.pi / 2, n)
    root = ROOT + np.linspace(0.0, 1.0, n)[:, None] * [1.0, 0.0, 0.0]
    motion = Motion(rot, root, 25.0)
    one = list(frames.iter_frames(motion, None, 64, 36, workers=1))
    two = list(frames.iter_frames(motion, None, 64, 36, workers=2))
    assert len(two) == n
    assert max(_differs(a, b) for a, b in zip(one, two, strict=True)) == 0
    assert _differs(two[0], two[-1]) > 50  # the frames really differ along the dance


def test_the_stage_draws_what_pyrender_draws() -> None:
    """The renderer's own OpenGL (meshes kept in GPU buffers, pyrender's shading written out) gives the picture
    that pyrender's scene renderer gives of the same figure, floor, shadows, lights and camera."""
    from dancenet_core import render
    from dancenet_core.kinematics import fk_numpy
    from dancenet_core.render.camera import _look_at
    from dancenet_core.render.geometry import _FLOOR_MARGIN, _blob_texture, _grid_texture
    from dancenet_core.render.stage import _Stage

    if render.gl_platform() != "egl":
        pytest.skip("pyrender draws without multisampling on OSMesa, so its picture is no reference there")
    import pyrender as pr  # once the platform is chosen

    motion = _tpose_and_raised_arm(ROOT)
    motion.rotations[1, JOINT_INDEX["right_knee"], 0] = -1.2  # a foot off the floor: a smaller, fainter shadow
    floor, camera = render.floor_height(motion), render.camera_path(motion, W, H)[1]
    pos, rot = fk_numpy(motion.skeleton, motion.rotations[1:], motion.root_positions[1:])
    stage = _Stage(motion, W, H, floor)
    fast = stage.render(pos[0], rot[0], camera)
    stage.close()  # before pyrender's own context: closing one ends EGL's display for both
    scene = pr.Scene(bg_color=[*(c / 255 for c in BACKGROUND_RGB), 1.0], ambient_light=stage._AMBIENT)
    vertices, normals = stage.figure.posed(pos[0], rot[0])
    scene.add(pr.Mesh([pr.Primitive(
        positions=vertices, normals=normals, color_0=stage.figure.colours, indices=stage.figure.faces,
        material=pr.MetallicRoughnessMaterial(metallicFactor=0.0, roughnessFactor=0.55))]))
    corners, uv = render.floor_quad(motion, floor)
    sampler = pr.Sampler(magFilter=pr.GLTF.LINEAR, minFilter=pr.GLTF.LINEAR_MIPMAP_LINEAR,
                         wrapS=pr.GLTF.REPEAT, wrapT=pr.GLTF.REPEAT)
    grid = pr.Texture(source=np.repeat(_grid_texture()[..., None], 3, axis=2), source_channels="RGB",
                      sampler=sampler)
    scene.add(pr.Mesh([pr.Primitive(
        positions=corners, normals=np.tile([0.0, 1.0, 0.0], (4, 1)), texcoord_0=uv,
        indices=np.array([[0, 1, 2], [0, 2, 3]]),
        material=pr.MetallicRoughnessMaterial(baseColorTexture=grid, metallicFactor=0.0, roughnessFactor=1.0))]))
    corners, alpha = stage.shadow_quads(pos[0])
    blob = np.zeros((*_blob_texture().shape, 4), np.uint8)
    blob[..., 3] = _blob_texture()
    n = len(corners) // 4
    scene.add(pr.Mesh([pr.Primitive(
        positions=corners, texcoord_0=(stage.shadow_corners[:, [0, 2]] + 1) / 2,
        color_0=np.column_stack([np.zeros((4 * n, 3)), alpha]),
        indices=(np.array([[0, 1, 2], [0, 2, 3]]) + 4 * np.arange(n)[:, None, None]).reshape(-1, 3),
        material=pr.MetallicRoughnessMaterial(
            baseColorFactor=[0.0, 0.0, 0.0, 1.0], alphaMode="BLEND", metallicFactor=0.0,
            baseColorTexture=pr.Texture(source=blob, source_channels="RGBA")))]))
    for direction, intensity in stage._LIGHTS:
        pose = _look_at(-np.asarray(direction), np.zeros(3))
        scene.add(pr.DirectionalLight(intensity=intensity), pose=pose)
    unit = render.figure_scale(motion.skeleton)
    scene.add(pr.PerspectiveCamera(yfov=render.YFOV, znear=0.05 * unit, zfar=4 * _FLOOR_MARGIN * unit),
              pose=camera.pose)
    reference = pr.OffscreenRenderer(W, H)
    expected, _ = reference.render(scene)
    reference.delete()
    diff = np.abs(fast.astype(int) - expected.astype(int))
    assert diff.mean() < 0.01  # a pixel's edge decided the other way here and there, nothing more
    assert (diff.max(axis=-1) > 8).mean() < 1e-3
    assert _differs(fast[H // 2, :], np.array(BACKGROUND_RGB)) > 40  # and there is a figure and floor to compare


def test_tessellation_follows_size_on_screen() -> None:
    """Segments around a part keep its facets within 0.5 px of the outline: 4 for a sub-pixel finger,
    10 for a 7-px limb (chord gap 7 * (1 - cos(pi / 10)) = 0.34 px; 8 would leave 0.53), capped at 24."""
    from dancenet_core import render
    from dancenet_core.render.geometry import _build_figure, _segments

    assert _segments(0.3) == 4
    assert _segments(7.0) == 10
    assert 7.0 * (1 - np.cos(np.pi / 8)) > 0.5 > 7.0 * (1 - np.cos(np.pi / 10))
    assert _segments(1e4) == 24
    unit = render.figure_scale(DEFAULT_SKELETON)
    small, large = (_build_figure(DEFAULT_SKELETON, unit, ppm) for ppm in (60.0, 360.0))
    assert len(small.faces) < len(large.faces) / 2


def test_a_stacked_contact_sheet_shows_each_dance_in_its_own_rows(tmp_path: Path) -> None:
    """Real above, generated below: one block of rows per motion, same moments, different pictures."""
    still, moving = _dance(20, 20.0), _dance(20, 20.0)
    still.rotations[:, JOINT_INDEX["left_shoulder"]] = 0.0  # arm down; the other one waves it
    sheet = contact_sheet([("real", still), ("DanceNet", moving)], tmp_path / "pair.png", cols=3, rows=1,
                          width=80, height=60)
    image = np.asarray(Image.open(sheet))
    assert image.shape[:2] == (2 * 60, 3 * 80)
    assert not np.array_equal(image[:60, 80:], image[60:, 80:])  # the moved figure differs after frame 0
