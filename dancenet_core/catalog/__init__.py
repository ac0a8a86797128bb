"""A song catalog danced in one run: `dancenet batch` and the add-on's batch mode share this runner.

The songs come from files, folders and lists (`songs.read_catalog`); each gets a folder of its own in the output
folder, named after it (`folders`), and the task a caller gives (`SongTask`) writes that folder's files. The
runner (`run.run_catalog`) adds what a catalog needs around it:

- isolation: a song that fails (a bad file, an exception, a worker process killed by the system) is reported
  and the others go on (`dance.dance_song`);
- resuming: each song folder has a record in OUT/.batch/ of the song and the request its files were made for
  (a hash of the song's bytes, its settings and the weights' bytes: `identity.request_id`), marked complete after
  the files, so a song whose files are all there for the same request is skipped and any other (never started,
  cut off by a kill, made for other settings) is made again; a killed run leaves whole files only (each is
  renamed into place); the songs' digests are remembered in OUT/.batch/ while their size and time stay the same;
- the user's files: a folder with no record of ours is never written into; the song takes the next free name;
- a status table, `batch.csv` and `batch.json` in the output folder, rewritten whole as songs end (`records`);
- where the songs run: in this process (`inline`: Blender), in `--jobs` worker processes of this machine
  (`local`), or as tasks on a Ray cluster (`cluster`), where the driver reads each song and sends its bytes, and
  the task sends the files back for the driver to write: the nodes share no folder.
"""

from __future__ import annotations

from .cluster import ray_module
from .dance import dance_song
from .identity import request_id
from .records import COLUMNS, KEPT, RECORDS, Status, finished
from .run import Report, Where, run_catalog
from .songs import CatalogSong, SongTask, read_catalog

__all__ = ["COLUMNS", "KEPT", "RECORDS", "CatalogSong", "Report", "SongTask", "Status", "Where", "dance_song",
           "finished", "ray_module", "read_catalog", "request_id", "run_catalog"]
