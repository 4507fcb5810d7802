"""Looking at runs: viewer export, movies and one-screen summaries of run files.

Modules (they read run files only through :mod:`tiltpile.store` and take every derived quantity
from :mod:`tiltpile.analysis`; nothing below ``view`` imports it):

``fields``   the per-grain and per-contact fields of each frame (active and mobilized contact
             numbers, critical-cluster id, failing grains) from the analysis library
``export``   extended XYZ (OVITO, ASE) and VTK XML (ParaView) writers
``movie``    the pile drawn as in the paper's Fig. 3, frame after frame, to mp4 or GIF
``info``     one-screen summaries (``tiltpile info``), a module by what each reads: a run file
             (``info.run``), an ensemble directory (``info.ensemble``), records
             (``info.records``)
``diagnostics``  per-frame health series of a run and the ensemble's first onsets
                 (``notebooks/run_diagnostics.ipynb``)
``output``   what every writer here shares: a progress bar over the frames, and a file written
             to a temporary name, then renamed
"""
