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

The table is data, written once: it never follows the code. A column whose code changes (its
producer's version bumped) gets a new code, which no entry here reaches, and its legacy records
stop serving it (the loader names it).

:data:`SUPERSEDED` carries records over a change of a column's code that kept its values:
{old code: new code}, followed transitively (an old code superseded twice reaches the latest).
Its entries are data, written once:

- those of the digest era (until 2026-12-05 a column's code was a digest of the code its producer
  reached, so that a refactor changing no value changed codes): each shown by
  ``python -m benchmarks.code_change OLD RUNS`` (the old commit's tables and the new one's on
  the same run files, every column, dtype and value, at the default parameters and others);
- the last digest of each producer, mapped to its versioned code (version 1 of every producer:
  :func:`tiltpile.analysis.tables.producer_code`), computed by the commit that introduced the
  versions from the same code (nothing else changed in that commit).

Since the versions, a refactor changes no code and needs no entry here; a changed value bumps its
producer's version, and records of the old version are refused (there is no entry to add: they
hold other values). A record's parameters are those its tables were computed at, a parameter it
predates at its default (:func:`tiltpile.analysis.ensemble_data.load_records`).
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


#: {old column code: new column code} of edits that kept the values (module docstring), by edit
SUPERSEDED: dict[str, str] = {
    # the contact rule, the lost-contact rule and the frame stride as analysis parameters
    # (contact_rule "force", lost_rule None, frame_stride 1 compute what the code of 8c18fdd
    # computed): every column, dtype and value the same on two smoke runs and a 1000-grain
    # default run at the default parameters and at cutoff 0.04; lost_gap 0.001 with link
    # "mobilized"; eps 0.01 with cluster_region "bulk" and min_contacts 3
    # (``python -m benchmarks.code_change 8c18fdd ...``)
    "0ad7a5d1a718a07d": "73fb9872a18c2807",
    "408f02d62f9afc36": "d5ff07d5f2e727a0",
    "440b34679cc6dce4": "918461df078b25ec",
    "583552aaba171ff1": "6fc5232d92908870",
    "5e3887203b2cf22b": "5092e23071329f99",
    "6a50ef0a2c8d093f": "f2d43c925168f634",
    "8a4a6bc40b5b065d": "7e24288b96fd3bb7",
    "ad9b82c639c6f7be": "f3545a0e2331705d",
    "cfd58215b2eeb946": "1cd00bc91c84e097",
    "d14989f26ca1e899": "f06031c175d9bbc1",
    "dff3888d398c31bb": "870c1882cd2e9931",
    "e425e2df3556231a": "3d425ab32762a813",
    "e94c194db3bb463e": "7630804d4594e1fa",
    "ee825aca3106d2c8": "896c87f40b9aa770",
    "f16336467ef6e9b8": "dfeb375021bc6b8a",
    "f36d47004273c630": "85dbc828f0647881",
    "f4ff9e43f323642a": "52ee6e7b15f1c3e0",
    "f51fc27e55eb2ec7": "d383a0eb5301dcc3",
    # the digests of the code of 605d1a5 (every record written since 8c18fdd holds them), to
    # version 1 of each producer (module docstring): the same code computes both
    "1cd00bc91c84e097": "866ddea72a25e780",
    "3d425ab32762a813": "3a1dc324f535577c",
    "5092e23071329f99": "0684b0bfd6feb371",
    "52ee6e7b15f1c3e0": "3a1dc324f535577c",
    "6fc5232d92908870": "efee82f0f4866ade",
    "73fb9872a18c2807": "8a27a84b77d4ef6c",
    "7630804d4594e1fa": "866ddea72a25e780",
    "7e24288b96fd3bb7": "e21c6f2f4a0e3c19",
    "85dbc828f0647881": "eea9a23ec49cd2a3",
    "870c1882cd2e9931": "866ddea72a25e780",
    "896c87f40b9aa770": "6cd9776062f66d9b",
    "918461df078b25ec": "8a27a84b77d4ef6c",
    "d383a0eb5301dcc3": "03f1d913d6c502fd",
    "d5ff07d5f2e727a0": "8a27a84b77d4ef6c",
    "dfeb375021bc6b8a": "c3ff12bc99c0c26b",
    "f06031c175d9bbc1": "dc6b123ca478996c",
    "f2d43c925168f634": "8a27a84b77d4ef6c",
    "f3545a0e2331705d": "8a27a84b77d4ef6c",
}


def superseded(code):
    """``code`` followed through :data:`SUPERSEDED` to the latest code that computes its values."""
    seen = set()
    while code in SUPERSEDED and code not in seen:
        seen.add(code)
        code = SUPERSEDED[code]
    return code


def recorded_column_code(meta: dict) -> dict | None:
    """The column codes a record's (or cache's) ``meta`` holds: {"frames": {column: digest},
    "clusters": {...}}, from its ``column_code``, or, for one written with a whole-table digest
    ``analysis_code``, its entry of :data:`LEGACY`; each code followed through :data:`SUPERSEDED`.
    None when it holds neither or an unknown ``analysis_code``."""
    codes = meta.get("column_code")
    if not isinstance(codes, dict):
        codes = LEGACY.get(meta.get("analysis_code"))
    if codes is None:
        return None
    return {t: {c: superseded(v) for c, v in cols.items()} for t, cols in codes.items()}
