"""Rigid clusters of a frame's frictional contact network: a (3,3) pebble game on a body-bar
framework (the rigidity matrix that checks it is a test oracle: tests/rigidity_oracles.py).

Henkes, Quint, Fily & Schwarz, PRL 116, 028301 (2016) and Liu, Kollmer, Daniels, Schwarz &
Henkes, PRL (2021) ("Spongelike rigid structures in frictional granular packings") decompose
frictional disk packings into rigid clusters by counting constraints; this module does the same
for one frame of a pile.

The framework (:func:`body_bar_framework`)
------------------------------------------
* Every disk is a rigid *body* with 3 degrees of freedom (x, y, rotation).
* The fixed bottom grains and the three walls are welded into one body, the *ground*
  (body 0, always present, even when nothing touches it).
* An active contact (f_n > 0) below the Coulomb threshold is 2 *bars* between its two bodies
  (normal and tangential); a fully mobilized one (``mobilized``, e.g. sliding) is 1 bar (normal).
  Contacts inside the ground (fixed-fixed, fixed-wall) are dropped.
* Left out (no body, label -1): rattlers, i.e. mobile grains with fewer than ``min_contacts``
  active contacts (:func:`tiltpile.analysis.contacts.rattler_mask`, single pass, as for z), their
  contacts, grains in ``exclude``, and mobile grains left with no contact at all once the
  rattlers' contacts are gone. ``n_left_out`` says how many.

The counting (:func:`pebble_game`)
----------------------------------
A (3,3) pebble game (Jacobs & Hendrickson, J. Comput. Phys. 137, 346 (1997); Lee & Streinu,
Discrete Math. 308, 1425 (2008)): each body holds 3 pebbles; a bar is *independent* when 4
pebbles can be gathered on its two ends (one is then spent to cover it), else *redundant*. By
Tay's theorem the independent bars are those of the generic body-bar rigidity matrix, so

    n_floppy = 3 n_bodies - n_independent - 3    (free pebbles left - the 3 rigid motions)

counts the motions relative to the ground. A piece of the network that touches neither the
ground nor anything attached to it (grains in flight) contributes its own 3 rigid motions.

Rigid clusters are the maximal (3,3)-tight sets of bodies (k bodies spanning 3k - 3 independent
bars). For (k,l) = (3,3) two tight sets sharing a body form a tight union, so the clusters
partition the bodies: every body has exactly one label, and a body rigidly attached to nothing is
a cluster of its own (size 1). They are found after the game (Lee & Streinu's component
detection): for an independent bar (u, v) whose ends are not yet labelled, gather pebbles on u
and v; if a fourth one comes, u and v are not rigid together; if only 3 come, the cluster is the
set of bodies from which, following the pebble game's directed bars, no free pebble other than
those on u and v can be reached (grown from u, v by searches against the bar directions).

Bars and clusters: a redundant bar always lies inside one cluster, but an independent bar need
not: the single bar of a sliding contact between two rigid blocks (or the 2 bars of a grain's only
sticking contact) joins two clusters and belongs to neither. ``bond_cluster`` is then
``FLOPPY_BOND`` (-2).

Labels (:func:`rigid_clusters`): the ground's cluster is label 0 (``GROUND``), then clusters by
decreasing size, ties by smallest grain index. Sizes count mobile grains only (the ground's fixed
grains are not counted: the ground's cluster can have size 0).

Spanning (:func:`spans`): a cluster spans the pile when it contains the ground and at least one
grain of the free surface (:func:`tiltpile.analysis.contacts.top_layer`). The side walls are part
of the ground, so a cluster reaching across the box from wall to wall is the ground's cluster too.

The independent check (tests/rigidity_oracles.py)
-------------------------------------------------
A body-bar framework's rigidity matrix has a row per bar and 3 columns (v_x, v_y, omega) per body,
the motion of the body about its reference point c. A bar along the unit direction u through the
point p between bodies a and b reads

    u . (v_a + omega_a z x (p - c_a)) - u . (v_b + omega_b z x (p - c_b)) = 0.

``generic_geometry`` draws p and u at random (a generic realization: Tay's theorem makes its
rank the pebble game's count); ``contact_geometry`` puts them where the disks touch (the
normal bar along the line of centres, the tangential one along the tangent). That is a special
position: rank is maximal at generic positions, so its rank can only be lower, its floppy modes
at least the pebble game's. ``matrix_floppy_modes`` is the nullity minus 3;
``matrix_rigid_clusters`` groups bodies that every null-space motion moves as one rigid body.

Floating point needs a rank tolerance, and real realizations of large near-isostatic frameworks
can be ill-conditioned: on smoke-run frames (250 grains) a random draw's smallest nonzero singular
value falls to 1e-11 of the largest, and one draw per frame with ``rtol = 1e-9`` mis-ranked 5 and
mis-clustered 17 of 753 frames of three smoke runs (other draws of those frames agree with the
pebble game). ``exact_generic_rigidity`` therefore builds the generic matrix over the
integers mod a prime, where rank and null space are exact; it agrees with the pebble game on
every frame tried (those 753, and 1000-grain frames of the default preset).

What the actual geometry adds (the same 753 frames, pebble game = exact generic count):

* exact extra modes (singular values below 1e-14 of the largest): 6 frames, +1 each. Seen: a
  *spinner*, a grain whose 3 or more contacts all slide, all with one rigid cluster (its normal
  bars pin its centre and leave its rotation free); a *gear pair*, two grains stuck together,
  each with its centre pinned by two sliding contacts on a rigid cluster (they counter-rotate);
  and a self-stress among three grains stacked against the right wall.
* near-special configurations: singular values from 1e-13 to 1e-7 of the largest, which move by
  orders of magnitude when the contact points move by 0.01 d; counted as zero with the default
  ``rtol = 1e-9``, they make 92 of the 753 frames differ from the pebble game (by 1 or 2), all
  but one of them frames where the pile moves (kinetic energy above 1e-4). The count at the
  actual geometry therefore depends on ``rtol``; the pebble game's does not.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit

from .contacts import _contact_counts, _rattler_mask, drop_contacts_of

GROUND = 0             # the ground's body index, and its cluster label in RigidityResult
NOT_IN_FRAMEWORK = -1  # bond_cluster of a contact giving no bar; grain_cluster of a left-out grain
FLOPPY_BOND = -2       # bond_cluster of a contact whose bars join two different rigid clusters

NORMAL = 0
TANGENTIAL = 1


# ----------------------------------------------------------------------------------------------
# the framework


class Framework(NamedTuple):
    """A frame's body-bar framework (module docstring).

    n_bodies : bodies, the ground (0) included.
    body : (N,) int, each grain's body: 0 for fixed grains, 1.. for kept mobile grains (in grain
        order), -1 for left-out grains.
    left_out : (N,) bool, mobile grains left out (rattlers, ``exclude``, no contact).
    n_rattlers : mobile grains left out as rattlers (part of ``left_out``).
    bar_a, bar_b : (B,) int, the bodies at the two ends of each bar (bar_a != bar_b).
    bar_contact : (B,) int, the contact (row of ``pair``) each bar comes from.
    bar_kind : (B,) int8, NORMAL (0) or TANGENTIAL (1).
    """
    n_bodies: int
    body: np.ndarray
    left_out: np.ndarray
    n_rattlers: int
    bar_a: np.ndarray
    bar_b: np.ndarray
    bar_contact: np.ndarray
    bar_kind: np.ndarray


def body_bar_framework(n: int, pair: np.ndarray, active: np.ndarray, mobilized: np.ndarray,
                       fixed: np.ndarray, exclude: np.ndarray | None = None,
                       min_contacts: int = 2) -> Framework:
    """The body-bar framework of a frame's contacts (module docstring).

    n grains; pair (C, 2) int (j < 0: walls); active, mobilized (C,) bool (mobilized is restricted
    to active contacts); fixed (N,) bool; exclude (N,) bool, mobile grains to leave out besides the
    rattlers (fixed grains in it are ignored: they are the ground); min_contacts: rattler
    threshold on the active contacts (0 keeps every grain that has a contact).

    Bars come in contact order, a contact's normal bar before its tangential one.
    """
    pair = np.asarray(pair, dtype=np.int64).reshape(-1, 2)
    fixed = np.asarray(fixed, dtype=bool)
    if fixed.shape != (n,):
        raise ValueError(f"body_bar_framework: fixed has shape {fixed.shape}, expected ({n},)")
    active = np.asarray(active, dtype=bool)
    mobilized = np.asarray(mobilized, dtype=bool) & active
    i, j = pair[:, 0], pair[:, 1]
    jj = np.maximum(j, 0)
    ground_j = (j < 0) | fixed[jj]
    use = active & ~(fixed[i] & ground_j)            # no contacts inside the ground
    z0 = _contact_counts(n, pair, active)
    ratt = _rattler_mask(z0, fixed, min_contacts)
    out = ratt.copy()
    if exclude is not None:
        out |= np.asarray(exclude, dtype=bool) & ~fixed
    use = drop_contacts_of(pair, use, out)
    out |= ~fixed & (_contact_counts(n, pair, use) == 0)
    body = np.full(n, -1, dtype=np.int64)
    body[fixed] = GROUND
    kept = ~fixed & ~out
    body[kept] = 1 + np.arange(int(kept.sum()))
    c = np.flatnonzero(use)
    nbars = np.where(mobilized[c], 1, 2)
    bar_contact = np.repeat(c, nbars)
    first = np.cumsum(nbars) - nbars                  # each contact's first bar: its normal one
    bar_kind = np.full(len(bar_contact), TANGENTIAL, dtype=np.int8)
    bar_kind[first] = NORMAL
    bar_a = body[i[bar_contact]]
    bar_b = np.where(j[bar_contact] >= 0, body[jj[bar_contact]], GROUND)
    return Framework(int(kept.sum()) + 1, body, out, int(ratt.sum()), bar_a, bar_b, bar_contact,
                     bar_kind)


# ----------------------------------------------------------------------------------------------
# the (3,3) pebble game


@njit(cache=True)
def _find_pebble(s, blocked, outs, deg, parent, seen, stamp, queue):
    """Bring one free pebble to body s (breadth-first along the directed bars, never through
    ``blocked``; -1 for none), reversing the path it came along. True if one came."""
    seen[s] = stamp
    if blocked >= 0:
        seen[blocked] = stamp
    queue[0] = s
    head, tail = 0, 1
    found = -1
    while head < tail and found < 0:
        x = queue[head]
        head += 1
        for q in range(deg[x]):
            y = outs[x, q]
            if seen[y] != stamp:
                seen[y] = stamp
                parent[y] = x
                if deg[y] < 3:
                    found = y
                    break
                queue[tail] = y
                tail += 1
    if found < 0:
        return False
    y = found
    while y != s:            # reverse s -> ... -> found: found spends a pebble, s gains one
        p = parent[y]
        for q in range(deg[p]):
            if outs[p, q] == y:
                outs[p, q] = outs[p, deg[p] - 1]
                break
        deg[p] -= 1
        outs[y, deg[y]] = p
        deg[y] += 1
        y = p
    return True


@njit(cache=True)
def _gather(a, b, target, outs, deg, parent, seen, stamp, queue):
    """Gather free pebbles on bodies a and b until they hold ``target`` (<= 6) or no more can
    come; returns the number they hold. ``stamp`` is a 1-element counter for ``seen``."""
    while 6 - deg[a] - deg[b] < target:
        if deg[a] > 0:
            stamp[0] += 1
            if _find_pebble(a, b, outs, deg, parent, seen, stamp[0], queue):
                continue
        if deg[b] > 0:
            stamp[0] += 1
            if _find_pebble(b, a, outs, deg, parent, seen, stamp[0], queue):
                continue
        break
    return 6 - deg[a] - deg[b]


@njit(cache=True)
def _grow_cluster(u, v, lab, label, adj_ptr, adj, outs, deg, cls, queue, cqueue, seen, stamp,
                  parent):
    """Label ``lab`` the rigid cluster of bodies u, v, which hold 3 free pebbles and can get no
    more: the bodies from which no free pebble other than those on u, v can be reached.

    cls: per body, 0 unknown, 1 in the cluster, 2 reaches a free pebble (reset on exit)."""
    ctail = 0
    for x in (u, v):
        if cls[x] != 1:
            cls[x] = 1
            label[x] = lab
            cqueue[ctail] = x
            ctail += 1
    # bodies known to reach a free pebble, listed to reset cls afterwards
    n_fail = 0
    fails = np.empty(16, dtype=np.int64)
    chead = 0
    while chead < ctail:
        x = cqueue[chead]
        chead += 1
        # the cluster is closed under the bar directions: outside neighbours point into it
        for q in range(adj_ptr[x], adj_ptr[x + 1]):
            w = adj[q]
            if cls[w] != 0:
                continue
            # breadth-first from w along the directed bars: does it reach a free pebble?
            stamp[0] += 1
            st = stamp[0]
            seen[w] = st
            queue[0] = w
            head, tail = 0, 1
            bad = -1
            if deg[w] < 3:
                bad = w
            while head < tail and bad < 0:
                y = queue[head]
                head += 1
                for r in range(deg[y]):
                    z = outs[y, r]
                    if seen[z] == st or cls[z] == 1:
                        continue
                    seen[z] = st
                    parent[z] = y
                    if cls[z] == 2 or deg[z] < 3:
                        bad = z
                        break
                    queue[tail] = z
                    tail += 1
            if bad < 0:
                for t in range(tail):         # everything w reaches is pebble-free: the cluster
                    y = queue[t]
                    cls[y] = 1
                    label[y] = lab
                    cqueue[ctail] = y
                    ctail += 1
            else:
                y = bad                       # the path w -> bad reaches a free pebble
                while True:
                    if cls[y] != 2:
                        cls[y] = 2
                        if n_fail == fails.shape[0]:
                            bigger = np.empty(2 * n_fail, dtype=np.int64)
                            bigger[:n_fail] = fails
                            fails = bigger
                        fails[n_fail] = y
                        n_fail += 1
                    if y == w:
                        break
                    y = parent[y]
    for t in range(ctail):
        cls[cqueue[t]] = 0
    for t in range(n_fail):
        cls[fails[t]] = 0
    return ctail


@njit(cache=True)
def _pebble_game(n, bar_a, bar_b):
    """(independent (B,) bool, cluster (n,) int in order of detection, free pebbles left)."""
    nb = bar_a.shape[0]
    outs = np.empty((n, 3), dtype=np.int64)
    deg = np.zeros(n, dtype=np.int64)
    parent = np.empty(n, dtype=np.int64)
    seen = np.zeros(n, dtype=np.int64)
    queue = np.empty(n, dtype=np.int64)
    stamp = np.zeros(1, dtype=np.int64)
    indep = np.zeros(nb, dtype=np.bool_)
    for e in range(nb):
        a, b = bar_a[e], bar_b[e]
        if a == b:
            continue                           # a bar from a body to itself constrains nothing
        if _gather(a, b, 4, outs, deg, parent, seen, stamp, queue) >= 4:
            indep[e] = True
            if deg[a] < 3:
                outs[a, deg[a]] = b
                deg[a] += 1
            else:
                outs[b, deg[b]] = a
                deg[b] += 1
    free = 3 * n - deg.sum()
    # undirected adjacency of the independent bars
    cnt = np.zeros(n + 1, dtype=np.int64)
    for e in range(nb):
        if indep[e]:
            cnt[bar_a[e] + 1] += 1
            cnt[bar_b[e] + 1] += 1
    adj_ptr = np.cumsum(cnt)
    fill = adj_ptr[:-1].copy()
    adj = np.empty(adj_ptr[n], dtype=np.int64)
    for e in range(nb):
        if indep[e]:
            a, b = bar_a[e], bar_b[e]
            adj[fill[a]] = b
            fill[a] += 1
            adj[fill[b]] = a
            fill[b] += 1
    label = np.full(n, -1, dtype=np.int64)
    cls = np.zeros(n, dtype=np.int8)
    cqueue = np.empty(n, dtype=np.int64)
    nlab = 0
    for e in range(nb):
        if not indep[e]:
            continue
        a, b = bar_a[e], bar_b[e]
        if label[a] >= 0 or label[b] >= 0:
            continue                          # clusters are disjoint and maximal: nothing new
        if _gather(a, b, 4, outs, deg, parent, seen, stamp, queue) >= 4:
            continue                          # a 4th pebble came: a and b are not rigid together
        _grow_cluster(a, b, nlab, label, adj_ptr, adj, outs, deg, cls, queue, cqueue, seen,
                      stamp, parent)
        nlab += 1
    for x in range(n):
        if label[x] < 0:
            label[x] = nlab
            nlab += 1
    return indep, label, free


class PebbleResult(NamedTuple):
    """Outcome of :func:`pebble_game`.

    n_floppy : free pebbles left - 3 (motions relative to any one body, e.g. the ground).
    independent : (B,) bool, the bars the game accepted (the others are redundant).
    cluster : (n_bodies,) int, rigid-cluster label of each body, 0..K-1 numbered by the smallest
        body in each cluster (so independent of the bar order).
    """
    n_floppy: int
    independent: np.ndarray
    cluster: np.ndarray


def pebble_game(n_bodies: int, bar_a: np.ndarray, bar_b: np.ndarray) -> PebbleResult:
    """(3,3) pebble game on the multigraph of ``n_bodies`` bodies and bars (bar_a[e], bar_b[e]).

    Bars are tried in the given order; which bars are called redundant depends on that order,
    their number, ``n_floppy`` and the clusters do not (module docstring). Cost (numba, after
    compilation): 40-160 ms for 4000 grains with 11 000-15 500 bars.
    """
    bar_a = np.ascontiguousarray(bar_a, dtype=np.int64).ravel()
    bar_b = np.ascontiguousarray(bar_b, dtype=np.int64).ravel()
    if bar_a.shape != bar_b.shape:
        raise ValueError("pebble_game: bar_a and bar_b differ in length")
    if n_bodies < 1:
        raise ValueError(f"pebble_game: need at least one body, got {n_bodies}")
    if bar_a.size and (min(bar_a.min(), bar_b.min()) < 0
                       or max(bar_a.max(), bar_b.max()) >= n_bodies):
        raise ValueError(f"pebble_game: bar ends must be bodies 0..{n_bodies - 1}")
    indep, label, free = _pebble_game(int(n_bodies), bar_a, bar_b)
    return PebbleResult(int(free) - 3, indep, canonical_labels(label))


def canonical_labels(label: np.ndarray) -> np.ndarray:
    """Relabel a partition 0..K-1 in the order of each part's smallest member."""
    label = np.asarray(label)
    _, first, inv = np.unique(label, return_index=True, return_inverse=True)
    order = np.argsort(np.argsort(first))
    return order[inv].astype(np.int64)


# ----------------------------------------------------------------------------------------------
# a frame's rigid clusters


class RigidityResult(NamedTuple):
    """Rigid clusters of a frame (:func:`rigid_clusters`; labels as in the module docstring).

    n_floppy : floppy modes (free pebbles - 3), relative to the ground.
    grain_cluster : (N,) int, cluster label of each grain; fixed grains carry the ground's label
        GROUND (0); -1 for left-out grains.
    bond_cluster : (C,) int, per contact: its cluster label when its bars lie inside one cluster,
        FLOPPY_BOND (-2) when they join two clusters, NOT_IN_FRAMEWORK (-1) when it gives no bar
        (open, inside the ground, or touching a left-out grain).
    cluster_size : (K,) int, mobile grains per label (the ground's fixed grains not counted).
    largest : label of the largest cluster (ties: the smallest label, so the ground's first).
    largest_size : its size (mobile grains).
    n_left_out : mobile grains left out (rattlers, ``exclude``, no contact).
    n_rattlers : of those, the rattlers.
    n_bodies : bodies in the game, the ground included.
    n_bars : bars in the game.
    n_redundant : redundant bars (n_bars - independent bars).
    """
    n_floppy: int
    grain_cluster: np.ndarray
    bond_cluster: np.ndarray
    cluster_size: np.ndarray
    largest: int
    largest_size: int
    n_left_out: int
    n_rattlers: int
    n_bodies: int
    n_bars: int
    n_redundant: int


def rigid_clusters(n: int, pair: np.ndarray, active: np.ndarray, mobilized: np.ndarray,
                   fixed: np.ndarray, exclude: np.ndarray | None = None,
                   min_contacts: int = 2) -> RigidityResult:
    """Floppy modes and rigid clusters of one frame (module docstring).

    n grains; pair (C, 2) int (j < 0: walls); active, mobilized (C,) bool, e.g. from
    :func:`tiltpile.analysis.observables.frame_contacts`; fixed (N,) bool; exclude (N,) bool
    extra mobile grains to leave out; min_contacts: rattler threshold (0: keep every grain with a
    contact). Returns a :class:`RigidityResult`.
    """
    fw = body_bar_framework(n, pair, active, mobilized, fixed, exclude, min_contacts)
    pg = pebble_game(fw.n_bodies, fw.bar_a, fw.bar_b)
    # labels: the ground's cluster first, then by decreasing size (mobile grains), ties by
    # smallest grain index (bodies are numbered in grain order)
    bodies_size = np.bincount(pg.cluster, weights=np.r_[0, np.ones(fw.n_bodies - 1)],
                              minlength=pg.cluster.max() + 1).astype(np.int64)
    k = bodies_size.size
    ground_c = pg.cluster[GROUND]
    others = np.array([c for c in range(k) if c != ground_c], dtype=np.int64)
    # canonical labels are in order of smallest body, so a stable sort keeps ties in grain order
    others = others[np.argsort(-bodies_size[others], kind="stable")]
    order = np.r_[ground_c, others].astype(np.int64)
    relabel = np.empty(k, dtype=np.int64)
    relabel[order] = np.arange(k)
    body_label = relabel[pg.cluster]
    cluster_size = bodies_size[order]
    grain_cluster = np.where(fw.body >= 0, body_label[np.maximum(fw.body, 0)], NOT_IN_FRAMEWORK)
    nc = np.asarray(pair).reshape(-1, 2).shape[0]
    bond_cluster = np.full(nc, NOT_IN_FRAMEWORK, dtype=np.int64)
    la, lb = body_label[fw.bar_a], body_label[fw.bar_b]
    bond_cluster[fw.bar_contact] = np.where(la == lb, la, FLOPPY_BOND)
    largest = int(np.argmax(cluster_size))
    return RigidityResult(
        n_floppy=pg.n_floppy, grain_cluster=grain_cluster.astype(np.int64),
        bond_cluster=bond_cluster, cluster_size=cluster_size, largest=largest,
        largest_size=int(cluster_size[largest]), n_left_out=int(fw.left_out.sum()),
        n_rattlers=fw.n_rattlers, n_bodies=fw.n_bodies, n_bars=int(fw.bar_a.size),
        n_redundant=int(fw.bar_a.size - pg.independent.sum()))


def spans(result: RigidityResult, top: np.ndarray, label: int | None = None) -> bool:
    """Does a rigid cluster span the pile? (module docstring)

    True when the cluster ``label`` (default: the largest, ``result.largest``) contains the ground
    (label GROUND) and at least one grain of ``top`` (N,) bool, the free-surface grains
    (:func:`tiltpile.analysis.contacts.top_layer`). Pass ``label=GROUND`` to ask whether the
    ground's cluster spans, largest or not.
    """
    label = result.largest if label is None else int(label)
    if label != GROUND:
        return False
    top = np.asarray(top, dtype=bool)
    return bool(np.any(result.grain_cluster[top] == GROUND))
