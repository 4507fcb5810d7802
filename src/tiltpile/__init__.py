"""tiltpile: a Contact Dynamics replication of Henkes, Brito, Dauchot & van Saarloos,
*Local Coulomb versus Global Failure Criterion for Granular Packings*.

Layers, from the bottom up (``LAYERS``). A module imports only from its own package and from
layers below its own, never from beside or above it; ``tests/test_layers.py`` enforces this and
that no import circle exists. At the bottom, importing nothing, lie the paper's values
(``paper_values``: each number of the paper that the code judges against or takes over, with
its source). Data then flows up: a configuration (``config``, its TOML presets in ``presets``)
is simulated (``sim``, numba kernels that know no files, or ``dem``, the
same protocol in LAMMPS), its output paths checked (``paths``) and its health judged
(``health``), its outputs written one writer at a time and replaced whole (``outputs``), written (``store``, the only HDF5 code; ``record``, what the figures keep of a
finished run), run one (``runner``; or imported from another code's frames, ``importers``) or
many at a time (``ensemble``), analysed (``analysis``),
drawn (``figures``) and judged against the paper (``report``), tilted on to its repose angle
(``repose``), studied beside the paper (``studies``), looked at (``view``)
and driven from the command line
(``cli``). Where each fact lives, and how to add to the code: docs/architecture.md. The measurements
(benchmarks) live beside the package, in the repository's ``benchmarks/``, and import it.

This package imports nothing itself, so that any layer may read ``tiltpile.__version__``.
"""

__version__ = "0.1.0"

# each entry: the subpackages and modules of one layer (names under tiltpile/)
LAYERS = (
    ("paper_values",),                    # the paper's values, each with its source
    ("config", "presets", "sim"),         # validated parameters and presets; the simulator
    ("dem",),                             # the second engine: soft-sphere DEM (LAMMPS)
    ("paths", "health", "outputs"),       # output paths; health limits of a run; output locks
    ("store", "record"),                  # the run file (HDF5); the run record (figures' inputs)
    ("runner", "importers"),              # one run: simulate, check health, write; or import one
    ("ensemble", "analysis"),             # many runs on dask; observables from run files
    ("figures", "report", "repose"),      # the paper's figures, the report, the repose angle
    ("studies",),                         # the side studies, one module each
    ("view",),                            # pictures and movies of one run
    ("cli",),                             # tiltpile <command>
    ("__main__",),                        # python -m tiltpile
)
