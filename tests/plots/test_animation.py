"""Animation: the face surface against an analytic case, frames, and reproducible files."""

import hashlib

import matplotlib

matplotlib.use("Agg")
import imageio.v2 as imageio  # noqa: E402
import numpy as np  # noqa: E402
import pytest  # noqa: E402
from matplotlib.figure import Figure  # noqa: E402
from PIL import Image  # noqa: E402

from facemotion.errors import InputError  # noqa: E402
from facemotion.plots.animation import (
    FaceAnimation,
    _fill_quads,
    _gif_durations_ms,
    _SurfaceInterpolator,
    animation_page,
    face_surface,
    frame_indices,
    render_frames,
    still_frame,
    write_animation,
)


def planar_face():
    """Markers on rings of an ellipse, on the plane z = 0.1 x + 0.2 y + 30 (mm)."""
    pts = [(0.0, 0.0)]
    for r in range(1, 5):
        a = np.linspace(0, 2 * np.pi, 8 + 2 * r, endpoint=False) + 0.3 * r
        pts += list(zip(18.0 * r * np.cos(a), 24.0 * r * np.sin(a), strict=True))
    xy = np.array(pts)
    return np.column_stack([xy, 0.1 * xy[:, 0] + 0.2 * xy[:, 1] + 30.0])


@pytest.fixture(scope="module")
def motion():
    neutral = planar_face()
    n = len(neutral)
    labels = [str(i + 1) for i in range(n)]
    T = 6
    t = np.arange(T) / 30.0
    jaw = np.clip(-neutral[:, 1] / 96.0, 0, 1)
    measured = np.zeros((T, n, 3))
    measured[..., 1] = -8.0 * np.sin(2 * np.pi * 2 * t)[:, None] * jaw
    measured[..., 2] = 2.0 * np.cos(2 * np.pi * 3 * t)[:, None] * jaw
    model = 0.8 * measured
    return neutral, labels, measured, model


def test_face_surface_reproduces_an_affine_displacement_field():
    neutral = planar_face()
    M = np.array([[0.02, -0.01, 0.0], [0.03, 0.05, 0.01], [-0.02, 0.04, 0.0]])
    b = np.array([1.0, -2.0, 0.5])
    displacement = neutral @ M.T + b
    X, Y, Z = face_surface(neutral, displacement, grid_n=25)
    assert X.shape == Y.shape == Z.shape == (25, 25)
    gx, gy = np.meshgrid(np.linspace(neutral[:, 0].min(), neutral[:, 0].max(), 25),
                         np.linspace(neutral[:, 1].min(), neutral[:, 1].max(), 25))
    inside = np.isfinite(X)
    assert 0.4 < inside.mean() < 0.95
    assert np.isnan(X[0, 0]) and np.isnan(Z[-1, -1])  # corners are outside the hull
    base = np.stack([gx, gy, 0.1 * gx + 0.2 * gy + 30.0], axis=-1)
    expected = base + base @ M.T + b
    got = np.stack([X, Y, Z], axis=-1)
    np.testing.assert_allclose(got[inside], expected[inside], atol=1e-5)
    # The per-frame interpolator used for rendering (a fixed linear map) gives the same
    # surface: exact for the affine field to 1e-8 mm, and face_surface's within its tolerance.
    fast = _SurfaceInterpolator(neutral, 25)(displacement)
    np.testing.assert_allclose(fast[..., :3][inside], expected[inside], atol=1e-8)
    np.testing.assert_allclose(fast[..., :3][inside], got[inside], atol=1e-5)
    np.testing.assert_allclose(fast[..., 3][inside],
                               np.linalg.norm(expected - base, axis=-1)[inside], atol=1e-5)


def test_face_surface_rejects_mismatched_shapes():
    neutral = planar_face()
    with pytest.raises(InputError, match="displacement"):
        face_surface(neutral, np.zeros((3, 3)))


def test_render_frames_are_fixed_size_deterministic_and_follow_the_motion(motion):
    neutral, labels, measured, model = motion
    frames = render_frames(neutral, measured, model, labels, ["1", "10"], fps=30.0, grid_n=20)
    assert len(frames) == len(measured)
    assert all(f.shape == (460, 800, 3) and f.dtype == np.uint8 for f in frames)
    again = render_frames(neutral, measured, model, labels, ["1", "10"], fps=30.0, grid_n=20)
    assert all(np.array_equal(a, b) for a, b in zip(frames, again, strict=True))
    assert not np.array_equal(frames[0], frames[1])  # the face moves
    # Main markers drawn in red (#EE6677) on both panels.
    red = np.all(np.abs(frames[0].astype(int) - [0xEE, 0x66, 0x77]) < 8, axis=-1)
    assert red[:, :380].sum() > 5 and red[:, 380:760].sum() > 5
    with pytest.raises(InputError, match="Chin"):
        render_frames(neutral, measured, model, labels, ["Chin"], fps=30.0)
    with pytest.raises(InputError, match="NaN"):
        bad = measured.copy()
        bad[0, 0, 0] = np.nan
        render_frames(neutral, bad, model, labels, ["1"], fps=30.0)


def test_still_frame_is_a_figure(motion):
    neutral, labels, measured, model = motion
    fig = still_frame(neutral, measured[2], model[2], labels, ["1", "10"], grid_n=20)
    assert isinstance(fig, Figure)
    panels = [ax for ax in fig.axes if ax.name == "3d"]
    assert [ax.get_title() for ax in panels] == ["measured",
                                               "model from the k = 2 main markers (red)"]
    assert all("mm" in ax.get_xlabel() and "mm" in ax.get_zlabel() for ax in panels)


def _agg_quads(quads, colours, h, w):
    """Quads drawn by matplotlib's Agg as an aliased PolyCollection (as Poly3DCollection draws
    the surface), in pixel coordinates with y down, onto white: the independent reference."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.collections import PolyCollection

    fig = Figure(figsize=(w / 100, h / 100), dpi=100)
    canvas = FigureCanvasAgg(fig)
    ax = fig.add_axes((0, 0, 1, 1))
    ax.set_axis_off()
    ax.set_xlim(0, w)
    ax.set_ylim(h, 0)
    ax.add_collection(PolyCollection(quads, facecolors=colours / 255.0, linewidths=0,
                                     antialiased=False))
    canvas.draw()
    return np.asarray(canvas.buffer_rgba())[..., :3].copy()


def _fill(quads, colours, h, w):
    img = np.full((h, w, 4), 255, dtype=np.uint8)
    _fill_quads(img, quads, colours)
    assert (img[..., 3] == 255).all()
    return img[..., :3]


def test_fill_quads_paints_the_pixels_agg_paints():
    # analytic: a rectangle covers the pixels it overlaps with positive area
    rect = np.array([[[2.5, 1.25], [5.5, 1.25], [5.5, 3.0], [2.5, 3.0]]])
    img = _fill(rect, np.array([[10, 20, 30]], np.uint8), 8, 9)
    painted = (img != 255).any(axis=-1)
    assert np.array_equal(np.argwhere(painted).min(0), [1, 2])  # rows 1-2, columns 2-5
    assert np.array_equal(np.argwhere(painted).max(0), [2, 5]) and painted.sum() == 8
    assert (img[painted] == [10, 20, 30]).all()
    # painter's order: the later of two overlapping quads is on top
    two = np.array([[[1, 1], [6, 1], [6, 6], [1, 6]], [[3, 3], [8, 3], [8, 8], [3, 8]]], float)
    img = _fill(two, np.array([[200, 0, 0], [0, 0, 200]], np.uint8), 10, 10)
    assert (img[4, 4] == [0, 0, 200]).all() and (img[2, 2] == [200, 0, 0]).all()
    # random quads (convex, darts, bow-ties, slivers, overlapping, some off the region)
    # against Agg's own aliased fill
    rng = np.random.default_rng(3)
    h, w, n = 90, 120, 400
    centre = rng.uniform([-5, -5], [w + 5, h + 5], size=(n, 1, 2))
    quads = centre + rng.normal(scale=rng.uniform(0.5, 8, size=(n, 1, 1)), size=(n, 4, 2))
    quads[:40, 1] = quads[:40, 3]  # degenerate corners
    colours = rng.integers(0, 250, size=(n, 3)).astype(np.uint8)
    ours, agg = _fill(quads, colours, h, w), _agg_quads(quads, colours, h, w)
    # Agg leaves out pixels a quad covers by less than 1/256: boundary pixels differ (2 %
    # here, with dense overlaps and many slivers)
    assert (ours == agg).all(axis=-1).mean() > 0.97
    assert ((ours != 255).any(-1) == (agg != 255).any(-1)).mean() > 0.985


def _background(anim):
    r = anim._r
    r.canvas.restore_region(r.background)
    return np.asarray(r.canvas.buffer_rgba())[..., :3].copy()


def test_projection_and_depth_order_are_matplotlibs(motion):
    neutral, labels, measured, model = motion
    anim = FaceAnimation(neutral, measured, model, labels, ["1", "10"], grid_n=20)
    r = anim._r
    r.draw(measured[2], model[2], "")
    r.rgb_reference()  # matplotlib projects and sorts the artists as it draws them
    for p, ax in enumerate(r.axes):
        grid, rgba, rest, main = r._scenes[p]
        px, py, pz = r.project(p, grid)
        order = np.argsort(np.average(pz[r._corner], axis=-1))[::-1]
        ours = np.stack([px, py], axis=-1)[r._corner[order]]
        poly = r.polys[p]
        theirs = np.array([ax.transData.transform(path.vertices[:4])
                           for path in poly.get_paths()])
        np.testing.assert_allclose(ours, theirs, atol=1e-9)
        np.testing.assert_array_equal(rgba[order], poly.get_facecolor())  # same depth order
        for line, pts in ((r.dots[p], rest), (r.mains[p], main)):
            mx, my, _ = r.project(p, pts)
            np.testing.assert_allclose(np.column_stack([mx, my]),
                                       ax.transData.transform(line.get_xydata()), atol=1e-9)


def bumpy_face():
    """planar_face with a nose: a bump 25 mm high, so that at the view's azimuth the surface
    hides part of itself (the painter's order matters)."""
    face = planar_face()
    face[:, 2] += 25.0 * np.exp(-(face[:, 0] ** 2 + face[:, 1] ** 2) / (2 * 22.0 ** 2))
    return face


@pytest.mark.parametrize("face", ["planar", "bumpy"])
def test_frames_look_like_matplotlibs_drawing(motion, face):
    neutral, labels, measured, model = motion
    if face == "bumpy":
        neutral = bumpy_face()
    anim = FaceAnimation(neutral, measured, model, labels, ["1", "10", "30"], grid_n=30)
    r = anim._r
    background = _background(anim)
    for i in (1, 4):
        ours = anim.frame(i, "caption")
        theirs = r.rgb_reference()  # the same frame drawn by matplotlib's artists
        diff = np.abs(ours.astype(int) - theirs).max(axis=-1)
        assert (diff == 0).mean() > 0.995 and (diff <= 3).mean() > 0.997
        face_ours = (ours != background).any(-1)
        face_theirs = (theirs != background).any(-1)
        assert face_theirs.sum() > 20000  # both surfaces are drawn
        assert (face_ours & face_theirs).sum() / (face_ours | face_theirs).sum() > 0.995
        box = [np.argwhere(m).min(0).tolist() + np.argwhere(m).max(0).tolist()
               for m in (face_ours, face_theirs)]
        assert np.abs(np.subtract(*box)).max() <= 1  # the silhouette in the same place


def test_colours_are_the_colormaps(motion):
    neutral, labels, measured, model = motion
    r = FaceAnimation(neutral, measured, model, labels, ["1"], grid_n=12)._r
    vmax = r.norm.vmax
    mag = np.concatenate([np.linspace(0.0, 2.0 * vmax, 10001), [vmax, np.nextafter(vmax, 0)]])
    np.testing.assert_array_equal(r._colour(mag), r.cmap(r.norm(mag)))


def test_still_shows_the_frame(motion):
    neutral, labels, measured, model = motion
    anim = FaceAnimation(neutral, measured, model, labels, ["1", "10"], grid_n=20)
    frame = anim.frame(3, "caption")
    fig = anim.still(3, "caption")
    fig.canvas.draw()
    still = np.asarray(fig.canvas.buffer_rgba())[..., :3]
    below = slice(40, None)  # the caption: Pillow's stamp in frames, matplotlib's in the still
    diff = np.abs(still[below].astype(int) - frame[below]).max(axis=-1)
    assert (diff == 0).mean() > 0.995


def test_frame_indices():
    idx, fps = frame_indices(361, 120.0, 30.0)
    assert fps == 30.0 and idx[:3].tolist() == [0, 4, 8] and idx[-1] == 360
    # never faster than asked: 100 Hz to at most 30 fps takes every 4th frame (25 fps)
    idx, fps = frame_indices(10, 100.0, 30.0)
    assert fps == 25.0 and idx.tolist() == [0, 4, 8]
    idx, fps = frame_indices(10, 25.0, 30.0)
    assert fps == 25.0 and idx.tolist() == list(range(10))


def test_gif_delays_keep_time():
    d = _gif_durations_ms(90, 30.0)
    assert set(d) <= {30, 40} and sum(d) == 3000


def _read(path):
    reader = imageio.get_reader(path)
    try:
        return [np.asarray(f) for f in reader.iter_data()], reader.get_meta_data()
    finally:
        reader.close()


def _sha(path):
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _frames(n=7, h=60, w=90):
    y, x = np.mgrid[0:h, 0:w]
    return [np.stack([(x * 3 + 20 * i) % 256, (y * 4) % 256, np.full_like(x, 40 * i % 256)],
                     axis=-1).astype(np.uint8) for i in range(n)]


@pytest.mark.parametrize("suffix", ["gif", "mp4"])
def test_written_animation_reads_back_and_is_byte_identical(tmp_path, suffix):
    frames = _frames()
    a, b = tmp_path / f"a.{suffix}", tmp_path / "sub" / f"b.{suffix}"
    write_animation(a, frames, fps=30.0)
    write_animation(b, frames, fps=30.0)
    assert _sha(a) == _sha(b)
    write_animation(a, frames, fps=30.0)  # overwrite in place: same bytes again
    assert _sha(a) == _sha(b)
    back, meta = _read(a)
    assert len(back) == len(frames)
    assert back[0].shape[:2] == (60, 90)
    if suffix == "gif":
        with Image.open(a) as im:
            assert im.n_frames == 7 and im.info["loop"] == 0
            assert im.info["duration"] == 30
        # No dithering and a 255-colour palette: these simple frames survive closely.
        assert np.abs(back[3][..., :3].astype(int) - frames[3]).mean() < 4
    else:
        assert meta["fps"] == pytest.approx(30.0)
        assert np.abs(back[3].astype(int) - frames[3]).mean() < 12  # lossy but close
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"a.{suffix}", "sub"]


def test_mp4_pads_odd_sizes(tmp_path):
    path = tmp_path / "odd.mp4"
    write_animation(path, _frames(3, 61, 91), fps=10.0)
    back, _ = _read(path)
    assert len(back) == 3 and back[0].shape[:2] == (62, 92)


def test_write_animation_rejects_bad_input(tmp_path):
    with pytest.raises(InputError, match="format"):
        write_animation(tmp_path / "a.avi", _frames(2), fps=10.0)
    with pytest.raises(InputError, match="frame 1"):
        write_animation(tmp_path / "a.gif", [_frames(1)[0], _frames(1, 10, 10)[0]], fps=10.0)
    with pytest.raises(InputError, match="no frames"):
        write_animation(tmp_path / "a.gif", [], fps=10.0)
    assert list(tmp_path.iterdir()) == []  # nothing half-written left behind


def test_face_animation_mp4_has_every_frame_and_is_byte_identical(motion, tmp_path):
    neutral, labels, measured, model = motion
    captions = [f"held-out sentence s07, frame {4 * i + 1} of 24 (t = {4 * i / 120:.2f} s)"
                for i in range(len(measured))]

    def write(path):
        anim = FaceAnimation(neutral, measured, model, labels, ["1", "10"], grid_n=15)
        write_animation(path, anim.frames(captions), fps=30.0)  # streamed, not listed
        return anim

    anim = write(tmp_path / "a.mp4")
    write(tmp_path / "b.mp4")
    assert _sha(tmp_path / "a.mp4") == _sha(tmp_path / "b.mp4")
    back, meta = _read(tmp_path / "a.mp4")
    assert len(back) == len(measured) and back[0].shape == (460, 800, 3)
    assert meta["fps"] == pytest.approx(30.0)
    # the frames decode close to what was rendered (lossy H.264)
    again = FaceAnimation(neutral, measured, model, labels, ["1", "10"], grid_n=15)
    ref = again.frame(3, captions[3])
    assert np.abs(back[3].astype(int) - ref).mean() < 6
    # the still of a frame is that frame, titled with its sentence and frame
    fig = anim.still(3, captions[3])
    assert "s07" in fig.texts[0].get_text() and "frame 13 of 24" in fig.texts[0].get_text()
    with pytest.raises(InputError, match="captions"):
        list(anim.frames(captions[:2]))


def test_animation_page_embeds_the_file(tmp_path):
    import base64

    path = tmp_path / "a.mp4"
    write_animation(path, _frames(3, 60, 90), fps=10.0)
    page = animation_page(path, "S1 <held-out>", "main markers: 40, 56").decode()
    src = page.split('src="data:video/mp4;base64,')[1].split('"')[0]
    assert base64.b64decode(src) == path.read_bytes()
    assert "S1 &lt;held-out&gt;" in page and "<video" in page
    assert animation_page(path, "S1 <held-out>", "main markers: 40, 56").decode() == page
    gif = tmp_path / "a.gif"
    write_animation(gif, _frames(3, 60, 90), fps=10.0)
    assert 'src="data:image/gif;base64,' in animation_page(gif, "t").decode()


def test_heldout_clip_captions_each_kept_frame_by_its_sentence():
    """Two held-out sentences of 10 and 7 frames at 120 Hz shown at up to 50 fps: every
    third frame (40 fps); each caption names the frame's sentence, its frame number there and
    its time; the still is the frame displaced most."""
    from facemotion.ingest.displacements import Displacements
    from facemotion.plots.animation import heldout_clip

    rng = np.random.default_rng(0)
    n, frames = 4, (10, 7)
    A = rng.normal(0, 1, (3 * sum(frames), n))
    A[3 * 12:3 * 14] *= 50  # frames 3 and 4 of the second sentence move most (only 3 is kept)
    row_sentence = np.concatenate([np.full(3 * f, s) for s, f in enumerate(frames)])
    row_frame = np.concatenate([np.repeat(np.arange(f), 3) for f in frames])
    F = A.shape[0] // 3
    part = Displacements(A, list("abcd"), ["s31", "s32"], row_sentence, row_frame, 120.0,
                         np.zeros((F, n), bool), np.zeros(F), np.zeros((n, 3)))
    clip = heldout_clip(part, 2 * A, 50.0, "S1")
    kept = [0, 3, 6, 9, 12, 15]
    assert clip.fps == 40.0 and len(clip.captions) == len(kept)
    np.testing.assert_array_equal(clip.measured[1], A[9:12].T)  # frame 3: rows 9-11
    np.testing.assert_array_equal(clip.model, 2 * clip.measured)
    assert clip.captions[0] == "S1: held-out sentence s31, frame 1 of 10 (t = 0.00 s)"
    assert clip.captions[3] == "S1: held-out sentence s31, frame 10 of 10 (t = 0.07 s)"
    assert clip.captions[4] == "S1: held-out sentence s32, frame 3 of 7 (t = 0.02 s)"
    assert kept[clip.largest_motion] == 12
