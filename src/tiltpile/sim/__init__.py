"""Contact Dynamics of rigid frictional disks in 2D (numba kernels; no I/O, no config parsing).

Modules, each owning one concept:

``scene``     grains, box and walls: sizes, masses, initial loose packing.
``detect``    candidate contacts from a cell list within an alert distance; warm-start matching.
``solver``    the nonlinear Gauss-Seidel (NLGS) sweep with the exact local 2D Coulomb solution.
``step``      one Moreau-Jean time step, and ``advance`` over many steps.
``protocol``  deposition until rest, then quasi-static tilt; yields frames and checkpoints.
``rng``       a small counter-free xorshift generator whose state is a checkpointable array.
``jit``       numba's JIT flags in one place, and a guard on numba's cache.
"""
