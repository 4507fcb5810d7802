"""tiltpile: a Contact Dynamics replication of Henkes, Brito, Dauchot & van Saarloos,
*Local Coulomb versus Global Failure Criterion for Granular Packings*.

Layers (imports point down): ``config`` -> ``sim`` (numba kernels) -> ``store`` (HDF5) ->
``ensemble`` -> ``analysis`` -> notebooks.
"""

__version__ = "0.1.0"
