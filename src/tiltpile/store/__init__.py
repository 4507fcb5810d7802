"""The run file: one HDF5 file per run. The only module that knows the layout.

Layout: ``LAYOUT`` declares every dataset (units and meaning, written with it as attributes
``units`` and ``description``) and ``ATTRS`` the attributes of the root and of the groups that
hold only attributes; docs/run-file.md shows both with shapes and types, and
tests/workflow/test_run_file_doc.py checks the page and a written file against them.

The file is written as ``NAME.part`` and renamed to ``NAME`` when complete, so a file with the
final name is always whole. An interrupted ``.part`` file resumes from its checkpoint
(``RunWriter.resume``): frames past the checkpoint are dropped and recomputed.

Checkpoints live in their own file, ``NAME.ckpt`` (HDF5: the simulator's full state as datasets,
attrs ``scalars`` (JSON), ``n_frames``, ``config_hash``, ``seed`` and ``frames_digest``), written
to a temporary name, synced and renamed, so a process killed at any moment leaves either the old
checkpoint or the new one, never a mixture. (HDF5 is not crash-safe for data rewritten in place:
a state rewritten inside the ``.part`` file could land in space the old one freed while the last
flushed metadata still described the old one, and a run killed then would resume from a mixture;
``test_sigkill_then_rerun_is_bit_identical`` kills runs at random moments.) The ``.part`` file is
flushed and synced before the checkpoint names its frame count; ``frames_digest`` (SHA-256 over
every frame and contact row written up to the checkpoint, in order) is checked on resume, so a
``.part`` file that lost or changed frames in a crash is started afresh rather than resumed.

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
messages for failed writes), ``digest`` (the attribute and frame digests), ``writer``
(``RunWriter``) and ``reader`` (``open_run``, ``verify``). Import from ``tiltpile.store``.
"""


from __future__ import annotations

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
           "acquire_lock", "checkpoint_path", "common_config", "has_integrity_record",
           "is_write_failure", "lock_path", "open_run", "part_path", "release_lock",
           "remove_stale_checkpoint", "verify", "write_error", "writer_lock"]
