"""Generation settings' defaults and limits that the command line, the add-on and batch mode share. This module
imports nothing, so the add-on reads them when it registers without loading the generator (numpy, scipy, numba)."""

# The frame rates animators and game engines work in; `--fps` offers these (film, PAL, NTSC, 50/60 Hz).
FRAME_RATES: tuple[int, ...] = (24, 25, 30, 50, 60)
# Root motion (shaping/rootmotion.py): travelling as danced, in place, or carried by a root bone on the floor.
ROOT_MODES: tuple[str, ...] = ("travel", "in-place", "root-bone")

# Sampling temperature (scales sigma within the drawn mixture component), chosen with the output smoothing on the
# validation songs (model card): below 1 each frame adds less than the model's own variance and the dance loses
# energy as it goes (temperature 0.1: FID_k 160 on the shipped weights before this model, 0.5: 102); at 1 with
# 1.5 frames of smoothing, 98, jitter as the real dancers'.
DEFAULT_TEMPERATURE = 1.0
# Above this the mixture's sigma swamps the dance (temperature 1e9 put the dancer 7e7 m away).
MAX_TEMPERATURE = 3.0
# The shortest part of a song worth dancing (a bar at 60 BPM is 4 s; one second still shows a move).
MIN_PART_S = 1.0
# A time-warp plays every frame within this share of the speed it was danced or captured at: the library engine's
# figures laid on the song's beats, and DanceNet's beat lock (`shaping/beatlock.py`).
WARP_RANGE = 0.15
