"""How alike a dance is where its song's music returns: the motion distance between the occurrences of one
section over the distance between different sections (0: a return danced exactly again; about 1: danced no more
alike than two different sections).

Sections are compared bar against bar over the shorter one's bars, at `POINTS_PER_BAR` points through each bar
(so a tempo drift between them does not count), as body poses: joint positions relative to the hips' place on
the floor, turned to face the same way (where on the floor and which way the dancer faces do not count).
"""

from __future__ import annotations

import itertools
from pathlib import Path

import numpy as np

from ..atomic import atomic_open
from ..errors import DanceNetError
from ..motion import Motion
from ..music.features import MusicAnalysis
from ..music.form import SongForm

POINTS_PER_BAR = 8


def body_poses(positions: np.ndarray, headings: np.ndarray) -> np.ndarray:
    """Joint positions [T, J, 3] relative to the hips' point on the floor, turned by -heading [T] about +Y."""
    local = positions - positions[:, :1] * np.array([1.0, 0.0, 1.0])
    c, s = np.cos(-headings)[:, None], np.sin(-headings)[:, None]
    x, z = local[..., 0], local[..., 2]
    return np.stack([c * x + s * z, local[..., 1], -s * x + c * z], axis=-1)


def return_likeness(positions: np.ndarray, headings: np.ndarray, fps: float, form: SongForm,
                    start_s: float = 0.0) -> float | None:
    """Mean pose distance between occurrences of the same section over that between different sections, for a
    dance (positions [T, J, 3] and headings [T], from `start_s` seconds into the song); None when the song has
    no return, or no two different sections, within the dance."""
    poses = body_poses(positions, headings)
    edges = form.bar_starts - start_s
    inside = [s for s in form.sections if edges[s.first_bar] >= 0 and edges[s.first_bar + s.bars] * fps <= len(poses)]
    same, different = [], []
    for a, b in itertools.combinations(inside, 2):
        bars = min(a.bars, b.bars)
        d = _distance(poses, edges, fps, a.first_bar, b.first_bar, bars)
        (same if a.label == b.label else different).append(d)
    if not same or not different:
        return None
    return float(np.mean(same) / np.mean(different))


def _distance(poses: np.ndarray, edges: np.ndarray, fps: float, a: int, b: int, bars: int) -> float:
    """Mean joint distance (m) between bars a.. and b.., bar against bar at POINTS_PER_BAR points each."""
    fraction = (np.arange(POINTS_PER_BAR) + 0.5) / POINTS_PER_BAR

    def frames(first: int) -> np.ndarray:
        starts, ends = edges[first:first + bars], edges[first + 1:first + bars + 1]
        t = (starts[:, None] + fraction[None] * (ends - starts)[:, None]).ravel()
        return np.clip(np.round(t * fps).astype(int), 0, len(poses) - 1)

    return float(np.linalg.norm(poses[frames(a)] - poses[frames(b)], axis=-1).mean())


def bar_poses(positions: np.ndarray, headings: np.ndarray, fps: float, edges: np.ndarray) -> np.ndarray:
    """[B, POINTS_PER_BAR * J * 3]: each bar's body poses at POINTS_PER_BAR points through it (`edges` the bar
    boundaries in the dance's seconds; bars outside the dance are left out by the caller)."""
    poses = body_poses(positions, headings)
    fraction = (np.arange(POINTS_PER_BAR) + 0.5) / POINTS_PER_BAR
    t = edges[:-1, None] + fraction[None] * np.diff(edges)[:, None]
    frames = np.clip(np.round(t * fps).astype(int), 0, len(poses) - 1)
    return poses[frames].reshape(len(edges) - 1, -1)


def form_figure(path: Path, analysis: MusicAnalysis, positions: np.ndarray, headings: np.ndarray, fps: float,
                form: SongForm, start_s: float, caption: str) -> None:
    """The song's form beside the dance's: bar against bar self-similarity of the music (chroma and onsets) and
    of the dance (body poses), the sections marked on both; a returning section shows as the same stripe in
    both where the dance repeats it."""
    from ..music.form import bar_features, self_similarity
    from ..plotting import pyplot

    edges = form.bar_starts
    inside = np.flatnonzero((edges[:-1] >= start_s) & (edges[1:] - start_s <= len(positions) / fps + 1e-6))
    if len(inside) < 2:
        raise DanceNetError("the dance is shorter than two bars of its song: no form to show")
    lo, hi = inside[0], inside[-1] + 1
    music = self_similarity(bar_features(analysis, edges))[lo:hi, lo:hi]
    poses = bar_poses(positions, headings, fps, edges[lo:hi + 1] - start_s)
    dist = np.linalg.norm(poses[:, None] - poses[None], axis=-1) / np.sqrt(poses.shape[1] / 3)
    plt = pyplot()
    fig, axes = plt.subplots(1, 2, figsize=(10, 5.2))
    for ax, matrix, title, cmap in ((axes[0], music, "music: bar against bar (chroma, onsets)", "viridis"),
                                    (axes[1], -dist, "dance: bar against bar (body poses)", "viridis")):
        ax.imshow(matrix, cmap=cmap, origin="upper", interpolation="nearest")
        ax.set_title(title, fontsize=10)
        ticks = [(s.first_bar - lo, s.name) for s in form.sections if lo <= s.first_bar < hi]
        ax.set_xticks([t for t, _ in ticks], [n for _, n in ticks], fontsize=8)
        ax.set_yticks([t for t, _ in ticks], [n for _, n in ticks], fontsize=8)
        for t, _ in ticks:
            ax.axhline(t - 0.5, color="white", lw=0.6)
            ax.axvline(t - 0.5, color="white", lw=0.6)
    fig.suptitle(caption, fontsize=10)
    fig.tight_layout()
    with atomic_open(path, "wb") as f:
        fig.savefig(f, format="png", dpi=100)
    plt.close(fig)


ARRANGED_SONGS = ("DANCE_W_1", "DANCE_W_2", "DANCE_W_4")  # three waltzes of the training split


def arranged_song(data_dir: Path, path: Path, form: str = "ABACAB", songs: tuple[str, ...] = ARRANGED_SONGS,
                  bars: int = 8) -> Path | None:
    """A song whose form is known: the sections `form` names, A, B, C, ... each the `bars` bars after the 4th
    downbeat of one of `songs` (Dance with Melody songs), cut on their downbeats; None without the data."""
    import soundfile as sf

    from ..music.features import analyze_music

    folder = data_dir / "dance_with_melody"
    if not all((folder / f"{s}.ogg").is_file() for s in songs):
        return None
    parts, rate = {}, 44100
    for letter, name in zip(sorted(set(form)), songs, strict=False):
        down = analyze_music(folder / f"{name}.ogg").downbeat_times
        audio, rate = sf.read(str(folder / f"{name}.ogg"), dtype="float32")
        parts[letter] = audio[int(down[4] * rate):int(down[4 + bars] * rate)]
    sf.write(str(path), np.concatenate([parts[c] for c in form]), rate)
    return path


def song_forms(pairs: list, data_dir: Path) -> dict[str, tuple[SongForm, float]]:
    """Each paired sequence's song form and where in the song its dance starts (the manifest's music offset)."""
    from ..data.dance_with_melody import read_manifest
    from ..music.features import analyze_music
    from ..music.form import song_form

    seqs = {s.seq: s for s in read_manifest(data_dir)}
    return {p.seq: (song_form(analyze_music(seqs[p.seq].audio)), float(seqs[p.seq].music_offset_s)) for p in pairs}


def mean_likeness(dances: list[Motion], positions: list[np.ndarray], songs: list[str],
                  forms: dict[str, tuple[SongForm, float]]) -> float | None:
    """The mean return likeness of the dances (their joint positions already computed) whose songs have returns
    within them (None: no such dance)."""
    from ..representation import heading_frames

    values = [return_likeness(p, heading_frames(m), m.fps, *forms[seq])
              for m, p, seq in zip(dances, positions, songs, strict=True) if seq in forms]
    values = [v for v in values if v is not None]
    return float(np.mean(values)) if values else None


def danced_again(dances: list[Motion], songs: list[str], forms: dict[str, tuple[SongForm, float]],
                 mode: str = "repeat") -> list[Motion]:
    """The dances with their songs' returns danced again, as `generate` dances them by default."""
    from ..shaping.repeats import dance_returns

    return [dance_returns(m, *forms[seq], mode)[0] for m, seq in zip(dances, songs, strict=True)]
