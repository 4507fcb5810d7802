"""The run file: one HDF5 file per run. The only module that knows the layout.

Layout: ``LAYOUT`` declares every dataset (units and meaning, written with it as attributes
``units`` and ``description``) and ``ATTRS`` the attributes of the root and of the groups that
hold only attributes; docs/run-file.md shows both with shapes and types, and
tests/workflow/test_run_file_doc.py checks the page and a written file against them.

While a run is written, ``NAME.part`` is not HDF5 but a frame log (``framelog``): an
append-only file of records (the head, the groups' attributes, each frame, a mark at each
checkpoint), never rewritten in place. When the run is complete, the writer builds the HDF5 run
file from the log under a temporary name, by the same HDF5 calls in the same order as when the
``.part`` itself was the HDF5 file (so the bytes are those of that file: only the wall times
differ), syncs it, notes its attribute digest at the log's end (``DONE``) and renames it to
``NAME``; then it removes the log and the checkpoint. So a file with the final name is always
whole, and the frames already written are never open for writing: HDF5 does not keep a file
readable through a kill in the middle of its own writes (before the log, 1 of 492 random kills
of a smoke run left its HDF5 ``.part`` unreadable), and the log needs no such care. An
interrupted ``.part`` resumes from its checkpoint (``RunWriter.resume``): the log is cut at the
length the checkpoint names and the frames past it are recomputed. A kill between the rename and
the removals leaves ``NAME`` with the log and checkpoint, which ``remove_stale_checkpoint``
removes when the log's ``DONE`` names ``NAME``'s digest (a killed ``--force`` rerun beside an
older ``NAME`` leaves no such record and resumes). An HDF5 ``.part`` and its checkpoint written
by a tiltpile before the frame log are resumed too: the ``.part`` is only read, its frames up to
the checkpoint become a log, and the run goes on from there.

Checkpoints live in their own file, ``NAME.ckpt`` (HDF5: the simulator's full state as datasets,
attrs ``scalars`` (JSON), ``n_frames``, ``config_hash``, ``seed``, ``frames_digest`` and
``log_bytes``), written to a temporary name, synced and renamed, so a process killed at any
moment leaves either the old checkpoint or the new one, never a mixture. (HDF5 is not
crash-safe for data rewritten in place: a state rewritten inside an HDF5 ``.part`` could land
in space the old one freed while the last flushed metadata still described the old one, and a
run killed then would resume from a mixture; ``test_sigkill_then_rerun_is_bit_identical`` kills
runs at random moments.) The log is synced before the checkpoint names its length;
``frames_digest`` (SHA-256 over every frame and contact row written up to the checkpoint, in
order) is checked on resume, so a ``.part`` that lost or changed frames is started afresh rather
than resumed.

One writer per run file. ``RunWriter`` (and ``runner.simulate`` around it) holds an exclusive
``flock`` on ``NAME.lock`` from before anything is opened or truncated until the run is finished
or closed; a second writer is refused with ``RunBusyError`` naming the ``.part`` file the other
process writes, and the lock file is removed by the last holder. (HDF5's own file lock is no
guard: ``h5py.File(part, "w")`` truncates the other writer's file before that lock refuses it.)

Integrity. A complete run file (root attr ``integrity = "fletcher32"``) has HDF5's Fletcher32
checksum on every chunk of every dataset (and ``attrs_sha256``, a SHA-256 over every attribute,
which ``verify`` checks): HDF5 checks the chunks' checksums on every read, so flipped bytes make a
read fail (``Run`` turns that into ``RunFileError`` naming the file and the dataset) instead of
returning wrong numbers. ``verify(path)`` reads every chunk and checks the layout (every dataset
present, the shapes consistent, ``complete``); ``open_run`` checks the layout, reads check the
checksums. Files written before the record existed have no ``integrity`` attr; they are checked
for layout only (``has_integrity_record``). A missing dataset is an error, except the
documented late additions ``frames/energy_gain`` (read as NaN) and ``/health`` (``Run.health``
empty) of files written before them.

Modules, one concern each: ``layout`` (what the file holds: ``LAYOUT``, ``ATTRS``, the filters),
``errors``, ``files`` (the ``.part``, ``.ckpt`` and ``.lock`` files beside a run file, syncing,
messages for failed writes), ``digest`` (the attribute and frame digests), ``framelog`` (the
``.part`` while a run is written), ``writer`` (``RunWriter``, which builds the run file) and
``reader`` (``open_run``, ``verify``). Import from ``tiltpile.store``.
"""


from __future__ import annotations

from tiltpile.store import framelog
from tiltpile.store.digest import _attrs_digest, _digest_frame
from tiltpile.store.errors import (MixedConfigError, RunBusyError, RunExistsError, RunFileError,
                                   RunWriteError)
from tiltpile.store.files import (_describe_os_error, _fsync, acquire_lock, checkpoint_path,
                                  is_write_failure, lock_path, part_path, release_lock,
                                  write_error, writer_lock)
from tiltpile.store.layout import (ATTRS, ATTRS_DIGEST, CONTACT_SETS, FILTERS, FRAME_ARRAYS,
                                   FRAME_SCALARS, INTEGRITY, LAYOUT, OPTIONAL, RESERVE_BYTES)
from tiltpile.store.reader import (Run, _layout_problems, common_config, has_integrity_record,
                                   open_run, verify)
from tiltpile.store.writer import _BROKEN, RunWriter, _create, remove_stale_checkpoint

__all__ = ["ATTRS", "ATTRS_DIGEST", "CONTACT_SETS", "FILTERS", "FRAME_ARRAYS", "FRAME_SCALARS",
           "INTEGRITY", "LAYOUT", "OPTIONAL", "RESERVE_BYTES", "MixedConfigError", "Run",
           "RunBusyError", "RunExistsError", "RunFileError", "RunWriteError", "RunWriter",
           "acquire_lock", "checkpoint_path", "framelog", "common_config", "has_integrity_record",
           "is_write_failure", "lock_path", "open_run", "part_path", "release_lock",
           "remove_stale_checkpoint", "verify", "write_error", "writer_lock"]
