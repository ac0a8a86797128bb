"""The motion library engine: a folder of real motion clips cut on the beats of a song.

- `analysis.py`: one clip's own beats (kinematic beats: minima of its joints' speed), tempo and bars read from its
  motion alone (the pose's return every bar, the steps' regularity, a style's known meter, the user's manifest),
  and the pose, velocity and foot contact at each beat (where a figure may be cut).
- `store.py`: a built library (every clip end to end, its beats and boundary features), saved and loaded as plain
  arrays, cached by the folder's content; what generation reads.
- `choreography.py`: choosing a figure for every bar of a song (dynamic programming over the bars: energy matched to
  the music, each figure laid 1:1, 2:1, 1:2, 3:2 or 2:3 on the song's beats so that it plays within +-15% of its
  captured speed, transition cost), time-warping each to the song's bars, and joining them
  (`transitions.py`: inertialised cuts, the root path carried).
- `build.py`: reading a folder of BVH clips (our 55 joints in any unit and up axis, or CMU's names, retargeted) into
  a library; torch-free and without `data/` (the add-on builds in Blender), never imported when dancing.
"""
