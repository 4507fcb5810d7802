"""The column codes of tables written before caches and records held one digest per column.

Until per-column digests (:func:`tiltpile.analysis.tables.column_code`), a record (and an
observables cache) held one digest of the whole table code, ``analysis_code``: tables.py and every
module of this package it imported, docstrings and comments aside (the former ``table_code()``).
:data:`LEGACY` maps each such digest whose code is known to the per-column digests of the
producers that compute the same values bit for bit, so that those records keep serving every
column whose code has not changed since, without being rewritten:

``11ce282f6e591a47``
    the table code of commits 88d2ef7 to fb26164 (2026-11-26 to 2026-12-01): it wrote the 58
    committed records of figures/paper/records and figures/paper-fresh/records, and writes
    those of any ensemble recorded with that code (the paper-fast runs among them). Its column
    codes are those of the producers of the commit that introduced them, which recompute the
    tables of that code bit for bit (checked on smoke runs at the default and at other analysis
    parameters, every column, dtype and value; tests/analysis/test_analysis_tables.py checks
    that the committed records hold exactly these columns).

The table is data, written once: it never follows the code. A column whose code changes gets a
new digest, which no entry here holds, and its legacy records stop serving it (the loader names
it).
"""

from __future__ import annotations

LEGACY = {
    "11ce282f6e591a47": {
        "frames": {
            "run": "dff3888d398c31bb",
            "frame": "dff3888d398c31bb",
            "step": "dff3888d398c31bb",
            "time": "dff3888d398c31bb",
            "theta_deg": "dff3888d398c31bb",
            "iterations": "dff3888d398c31bb",
            "residual": "dff3888d398c31bb",
            "n_mobile": "ad9b82c639c6f7be",
            "n_bulk": "408f02d62f9afc36",
            "n_rattlers": "408f02d62f9afc36",
            "z": "408f02d62f9afc36",
            "n_m": "408f02d62f9afc36",
            "dz_gen": "408f02d62f9afc36",
            "z_all": "d14989f26ca1e899",
            "n_m_all": "d14989f26ca1e899",
            "dz_gen_all": "d14989f26ca1e899",
            "z_rest": "f4ff9e43f323642a",
            "n_rest": "f4ff9e43f323642a",
            "n_active": "ad9b82c639c6f7be",
            "n_mobilized": "ad9b82c639c6f7be",
            "ke_trans": "e94c194db3bb463e",
            "ke_rot": "e94c194db3bb463e",
            "n_lost": "440b34679cc6dce4",
            "lost_fraction": "440b34679cc6dce4",
            "n_failing": "440b34679cc6dce4",
            "n_failing_in_cluster": "440b34679cc6dce4",
            "failing_in_cluster_fraction": "440b34679cc6dce4",
            "largest_cluster": "5e3887203b2cf22b",
            "n_clusters": "5e3887203b2cf22b",
            "n_in_clusters": "5e3887203b2cf22b",
            "cluster_fraction": "5e3887203b2cf22b",
            "rigid_fraction": "6a50ef0a2c8d093f",
            "floppy_per_grain": "6a50ef0a2c8d093f",
            "rigid_spanning": "6a50ef0a2c8d093f",
            "n_rigid_left_out": "6a50ef0a2c8d093f",
            "avalanching": "f36d47004273c630",
            "onset": "f36d47004273c630",
            "period": "f36d47004273c630",
            "theta_m": "583552aaba171ff1",
            "theta_to_onset": "583552aaba171ff1",
            "mean_displacement": "8a4a6bc40b5b065d",
            "max_displacement": "8a4a6bc40b5b065d",
        },
        "clusters": {
            "run": "cfd58215b2eeb946",
            "frame": "cfd58215b2eeb946",
            "theta_deg": "0ad7a5d1a718a07d",
            "avalanching": "f16336467ef6e9b8",
            "theta_to_onset": "f16336467ef6e9b8",
            "cluster": "e425e2df3556231a",
            "size": "e425e2df3556231a",
            "z": "e425e2df3556231a",
            "n_m": "e425e2df3556231a",
            "dz": "e425e2df3556231a",
            "orientation_deg": "e425e2df3556231a",
            "phi_deg": "e425e2df3556231a",
            "rg_long": "e425e2df3556231a",
            "rg_short": "e425e2df3556231a",
            "x_com": "e425e2df3556231a",
            "y_com": "e425e2df3556231a",
            "n_unstable": "ee825aca3106d2c8",
            "speed_max": "f51fc27e55eb2ec7",
        },
    },
}


def recorded_column_code(meta: dict) -> dict | None:
    """The column codes a record's (or cache's) ``meta`` holds: {"frames": {column: digest},
    "clusters": {...}}, from its ``column_code``, or, for one written with a whole-table digest
    ``analysis_code``, its entry of :data:`LEGACY`. None when it holds neither or an unknown
    ``analysis_code``."""
    codes = meta.get("column_code")
    if isinstance(codes, dict):
        return codes
    legacy = LEGACY.get(meta.get("analysis_code"))
    return None if legacy is None else {t: dict(c) for t, c in legacy.items()}
