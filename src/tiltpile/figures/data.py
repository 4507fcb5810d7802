"""What every figure notebook starts from: the ensemble tables, its description, sample frames.

:class:`Ensemble` and :func:`load_ensemble` live in :mod:`tiltpile.analysis.ensemble_data` (the
measurement studies use them too); they are re-exported here for the notebooks.
"""

from __future__ import annotations

from tiltpile.analysis.ensemble_data import Ensemble, load_ensemble

__all__ = ["Ensemble", "load_ensemble", "snapshot"]


def snapshot(ens: Ensemble, seed: int, frame: int) -> dict:
    """Positions, radii, contacts of one stored frame, and the contacts and positions of the next
    (``next``, ``next_position``; None at the last frame), for the pile pictures of Figs. 1b and 3.

    From the run file, or, for an ensemble loaded from records, from the run's record, which
    holds the frames the pictures choose by default (``tiltpile.record.RecordError`` for another)."""
    if ens.records:
        from tiltpile.record import read_record
        return read_record(ens.record_path(seed), tables=False).snapshot(frame)
    from tiltpile.store import open_run
    with open_run(ens.run_path(seed)) as r:
        pair, force, status = r.contacts(frame)
        last = frame + 1 >= r.n_frames
        return {"position": r.position(frame), "radius": r.radius, "fixed": r.fixed,
                "pair": pair, "force": force, "status": status, "theta_deg": float(r.theta_deg[frame]),
                "box_length": r.box_length, "next": None if last else r.contacts(frame + 1),
                "next_position": None if last else r.position(frame + 1)}
