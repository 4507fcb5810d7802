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
            "run": "38740293541250bd",
            "frame": "38740293541250bd",
            "step": "38740293541250bd",
            "time": "38740293541250bd",
            "theta_deg": "38740293541250bd",
            "iterations": "38740293541250bd",
            "residual": "38740293541250bd",
            "n_mobile": "9308e5bc7ea23f00",
            "n_bulk": "5f75893b4bb72fab",
            "n_rattlers": "5f75893b4bb72fab",
            "z": "5f75893b4bb72fab",
            "n_m": "5f75893b4bb72fab",
            "dz_gen": "5f75893b4bb72fab",
            "z_all": "adfaab2426fd8484",
            "n_m_all": "adfaab2426fd8484",
            "dz_gen_all": "adfaab2426fd8484",
            "z_rest": "06d9bf44377082bc",
            "n_rest": "06d9bf44377082bc",
            "n_active": "9308e5bc7ea23f00",
            "n_mobilized": "9308e5bc7ea23f00",
            "ke_trans": "f3d5f5ca3b69a39b",
            "ke_rot": "f3d5f5ca3b69a39b",
            "n_lost": "45fec7fa94364228",
            "lost_fraction": "45fec7fa94364228",
            "n_failing": "45fec7fa94364228",
            "n_failing_in_cluster": "45fec7fa94364228",
            "failing_in_cluster_fraction": "45fec7fa94364228",
            "largest_cluster": "fa4c87949a80855d",
            "n_clusters": "fa4c87949a80855d",
            "n_in_clusters": "fa4c87949a80855d",
            "cluster_fraction": "fa4c87949a80855d",
            "rigid_fraction": "7029e33a143b0bb0",
            "floppy_per_grain": "7029e33a143b0bb0",
            "rigid_spanning": "7029e33a143b0bb0",
            "n_rigid_left_out": "7029e33a143b0bb0",
            "avalanching": "f787d1b728241007",
            "onset": "f787d1b728241007",
            "period": "f787d1b728241007",
            "theta_m": "69ac31d228a2d993",
            "theta_to_onset": "69ac31d228a2d993",
            "mean_displacement": "b396771b29e97502",
            "max_displacement": "b396771b29e97502",
        },
        "clusters": {
            "run": "5078b20fe332f838",
            "frame": "5078b20fe332f838",
            "theta_deg": "4255ed6b6879bb6b",
            "avalanching": "612473dc4769c485",
            "theta_to_onset": "612473dc4769c485",
            "cluster": "eabf0587c29d14f0",
            "size": "eabf0587c29d14f0",
            "z": "eabf0587c29d14f0",
            "n_m": "eabf0587c29d14f0",
            "dz": "eabf0587c29d14f0",
            "orientation_deg": "eabf0587c29d14f0",
            "phi_deg": "eabf0587c29d14f0",
            "rg_long": "eabf0587c29d14f0",
            "rg_short": "eabf0587c29d14f0",
            "x_com": "eabf0587c29d14f0",
            "y_com": "eabf0587c29d14f0",
            "n_unstable": "efa3eaf76ec3ad2d",
            "speed_max": "e289345a8a5b7c9d",
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
