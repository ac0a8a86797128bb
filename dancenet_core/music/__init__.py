"""Music in, what the dance hears out: decoding and resampling (`audio`), the 15 features at 10 fps with
beats and downbeats, cached by content (`features`, its madmom networks run by a compiled loop in
`madmom_nets`), and the trained style classifier (`style`, inference only). Imports nothing from the
dance model, the data, training, evaluation or the commands."""

from .madmom_metadata import register as _register_madmom_metadata

_register_madmom_metadata()  # before anything here imports madmom
