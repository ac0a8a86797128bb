"""The steps that shape a danced motion into the dance that is written or keyed, in their one order.

Inside an engine (the DanceNet engine; the library's frames are real capture, placed and blended by its own
`library/transitions.py`):
  1. `beatlock.py`      the dance's own beats moved onto the song's (a time warp within `constants.WARP_RANGE`)
  2. `footlock.py`      feet that the foot model says stand are held where they stand
  3. `floor.py`         the dance set on the floor (the lower toe where the floor is)
  4. `continuation.py`  a continued dance joins the kept one with no jump
After the engine (and any section it danced anew with settings of its own: `generate.py`), for every engine:
  5. `repeats.py`       the song's returning sections danced as their first hearing (`placing.py` lays a copy where
                        the dancer stands), the foot contacts and the figure list (`figures.py`) following
                        (`takes.with_repeats`)
Then the one output path (`takes.shape_takes`, the command line's and the add-on's):
  6. resampled to the frame rate asked for, a continued dance's kept frames exactly as they were
     (`continuation.keep_original`), and the root motion applied (`rootmotion.apply_mode`).

The package sits below the engines, which call its steps: it imports no engine, and its `__init__` imports
nothing, so a foundation module (`continuation`, `floor`, `footlock`, `rootmotion`) stays free of the
music.
"""
