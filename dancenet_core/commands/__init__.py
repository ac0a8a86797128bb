"""The `dancenet` subcommands: one module a command, each declaring its own options (`add_arguments`) and
setting the function that runs it (`handler`). Only the command being run is imported, so `dancenet --help`
and every command's start stay free of what the others load (torch above all).

The table below is what `dancenet --help` lists; a command `x-y` lives in `commands/x_y.py`.
"""

COMMANDS: dict[str, str] = {
    "generate": "generate a dance for a song (BVH, .npz and a JSON summary)",
    "batch": "dance a catalog of songs: worker processes or a Ray cluster, resumable (one folder a song)",
    "analyze": "print a song's tempo, style, beats and downbeats",
    "render": "render a motion (BVH or .npz) as a preview video with its music",
    "data": "build or inspect the training dataset",
    "library": "build a motion library from a folder of BVH clips (for --engine library)",
    "train": "train DanceNet, the foot model or a style classifier",
    "card": "rewrite a model card from trained weights",
    "evaluate": "the paper's comparison table on the test split (trains what is missing)",
    "validate": "DanceNet's sampling settings scored on the validation songs",
    "weights": "convert trusted weights files of the old pickled format",
}
