"""numba kernels of the distance engine: pose check, dual-tree search, closest-pair answer.

Every kernel is compiled eagerly with an explicit signature (``cache=True``; the one JIT
strategy of the package, see ``reachwise.kinematics._jit``), so that
importing this module compiles them once (or loads them from numba's on-disk cache) and
a query never compiles: a call with other argument types raises ``TypeError`` instead.
None uses ``parallel=True``, BLAS or threads; one query runs on one core.

The tree the queries walk is built by :func:`reachwise.distance._build.build_tree` (a
linear BVH in Morton order): nodes in depth-first order (node ``k``'s left child is
``k + 1``, its right child ``info[k, 2]``, ``-1`` for a leaf), each covering the
contiguous range ``info[k, 0]:info[k, 1]`` of the tree-ordered points with their tight
box, leaves of at most ``leaf_size`` (≤ :data:`LEAF_MAX`) points.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from numba import njit, types

#: Largest leaf size the query kernel accepts (its per-leaf scratch arrays).
LEAF_MAX = 64

# --------------------------------------------------------------------------- poses


@njit("int64(float64[:, ::1])", cache=True, nogil=True)
def pose_status(P):  # type: ignore[no-untyped-def]
    """0: a rigid pose to 1e-12; 1: NaN/inf; 2: bottom row is not 0 0 0 1;
    3: the rotation needs the careful (Python) check."""
    for i in range(4):
        for j in range(4):
            if not np.isfinite(P[i, j]):
                return 1
    if P[3, 0] != 0.0 or P[3, 1] != 0.0 or P[3, 2] != 0.0 or P[3, 3] != 1.0:
        return 2
    dev = 0.0
    for i in range(3):
        for j in range(3):
            g = P[0, i] * P[0, j] + P[1, i] * P[1, j] + P[2, i] * P[2, j]
            if i == j:
                g -= 1.0
            dev = max(dev, abs(g))
    det = (
        P[0, 0] * (P[1, 1] * P[2, 2] - P[1, 2] * P[2, 1])
        - P[0, 1] * (P[1, 0] * P[2, 2] - P[1, 2] * P[2, 0])
        + P[0, 2] * (P[1, 0] * P[2, 1] - P[1, 1] * P[2, 0])
    )
    if dev > 1e-12 or det <= 0.0:
        return 3
    return 0


# --------------------------------------------------------------------------- dual tree


@njit(cache=True, nogil=True, inline="always")
def _gap2(a, i, b, j):  # type: ignore[no-untyped-def]
    """Squared distance between box row i of ``a`` and box row j of ``b`` (lo|hi rows)."""
    g = 0.0
    for c in range(3):
        d = a[i, c] - b[j, c + 3]
        if d > 0.0:
            g += d * d
        else:
            d = b[j, c] - a[i, c + 3]
            if d > 0.0:
                g += d * d
    return g


@njit(
    "void(float64[::1], float64[::1], float64[::1], float64[::1], float64, float64[::1])",
    cache=True,
    nogil=True,
)
def finish(pa, pb, ca, cb, margin, out):  # type: ignore[no-untyped-def]
    """Fill ``out`` = [distance, pa, pb, direction] from world points ``pa``, ``pb``.

    The direction is ``(pa - pb) / distance``; at distance 0 it is the unit vector from
    the centroid ``cb`` of cloud b to the centroid ``ca`` of cloud a (pushing a out of
    b), and +z if those coincide too.
    """
    dx = pa[0] - pb[0]
    dy = pa[1] - pb[1]
    dz = pa[2] - pb[2]
    d = np.sqrt(dx * dx + dy * dy + dz * dz)
    out[0] = d
    for i in range(3):
        out[1 + i] = pa[i]
        out[4 + i] = pb[i]
    if d > 0.0:
        out[7] = dx / d
        out[8] = dy / d
        out[9] = dz / d
        return
    dx = ca[0] - cb[0]
    dy = ca[1] - cb[1]
    dz = ca[2] - cb[2]
    n = np.sqrt(dx * dx + dy * dy + dz * dz)
    if n > 0.0:
        out[7] = dx / n
        out[8] = dy / n
        out[9] = dz / n
    else:
        out[7] = 0.0
        out[8] = 0.0
        out[9] = 1.0


@njit(cache=True, nogil=True, inline="always")
def _pgap2(x, y, z, box, k):  # type: ignore[no-untyped-def]
    """Squared distance from point (x, y, z) to box row k (lo|hi)."""
    g = 0.0
    d = max(box[k, 0] - x, x - box[k, 3])
    if d > 0.0:
        g += d * d
    d = max(box[k, 1] - y, y - box[k, 4])
    if d > 0.0:
        g += d * d
    d = max(box[k, 2] - z, z - box[k, 5])
    if d > 0.0:
        g += d * d
    return g


@njit(cache=True, nogil=True)
def _descend(x, y, z, pts, box, info, root, best2, st, gs):  # type: ignore[no-untyped-def]
    """Nearest point of the subtree ``root`` to (x, y, z) if closer than sqrt(best2):
    returns (its squared distance, its tree index), or (best2, -1) if none is."""
    bj = -1
    g = _pgap2(x, y, z, box, root)
    if g >= best2:
        return best2, bj
    st[0] = root
    gs[0] = g
    sp = 1
    while sp > 0:
        sp -= 1
        k = st[sp]
        if gs[sp] >= best2:
            continue
        r = info[k, 2]
        if r < 0:
            for q in range(info[k, 0], info[k, 1]):
                dx = x - pts[q, 0]
                dy = y - pts[q, 1]
                dz = z - pts[q, 2]
                d2 = dx * dx + dy * dy + dz * dz
                if d2 < best2:
                    best2 = d2
                    bj = q
            continue
        c1 = k + 1
        c2 = r
        g1 = _pgap2(x, y, z, box, c1)
        g2 = _pgap2(x, y, z, box, c2)
        if g1 > g2:
            c1, c2 = c2, c1
            g1, g2 = g2, g1
        if g2 < best2:
            st[sp] = c2
            gs[sp] = g2
            sp += 1
        if g1 < best2:
            st[sp] = c1
            gs[sp] = g1
            sp += 1
    return best2, bj


class TreeArrays(NamedTuple):
    """One indexed cloud as the query kernels read it
    (:class:`~reachwise.distance.index.CloudIndex`'s arrays, in its own frame, m):
    ``points`` (N, 3) in tree order, ``boxes`` (M, 6) node AABBs (lo | hi), ``info``
    (M, 3) start, end and right child of each node, ``perm`` (N,) the input row of
    each tree point, ``centroid`` (3,) the mean point."""

    points: np.ndarray
    boxes: np.ndarray
    info: np.ndarray
    perm: np.ndarray
    centroid: np.ndarray


class QueryScratch(NamedTuple):
    """Scratch of one dual-tree query, owned by the caller and overwritten (nothing is
    allocated during a query): ``tbox`` (≥ M_A, 6) A's node boxes mapped into B's
    frame, ``tdone`` (≥ M_A) which are mapped, ``tp`` (≥ N_A, 3) A's mapped leaf
    points, ``done`` (≥ M_A) which leaves are mapped, ``stack_i`` (:data:`STACK_INTS`)
    and ``stack_g`` (:data:`STACK_FLOATS`) the search stacks, ``vec`` (4, 3) the world
    points and centroids of the answer."""

    tbox: np.ndarray
    tdone: np.ndarray
    tp: np.ndarray
    done: np.ndarray
    stack_i: np.ndarray
    stack_g: np.ndarray
    vec: np.ndarray


_F2 = types.float64[:, ::1]
_I2 = types.int64[:, ::1]
_F1 = types.float64[::1]
_I1 = types.int64[::1]
_B1 = types.boolean[::1]
#: numba type of a :class:`TreeArrays`.
TREE = types.NamedTuple((_F2, _F2, _I2, _I1, _F1), TreeArrays)


def new_scratch(max_nodes: int, max_points: int) -> QueryScratch:
    """Scratch for queries whose A cloud has at most ``max_nodes`` tree nodes and
    ``max_points`` points."""
    m = max(1, max_nodes)
    return QueryScratch(
        np.empty((m, 6)),
        np.zeros(m, np.bool_),
        np.empty((max(1, max_points), 3)),
        np.zeros(m, np.bool_),
        np.empty(STACK_INTS, np.int64),
        np.empty(STACK_FLOATS),
        np.empty((4, 3)),
    )


#: Depth of the node-pair stack and of the point-descent stack of one query.
STACK = 512
POINT_STACK = 256
#: Lengths of the integer and float stack scratch one query needs.
STACK_INTS = 2 * STACK + LEAF_MAX + POINT_STACK
STACK_FLOATS = STACK + LEAF_MAX + POINT_STACK


@njit(cache=True, nogil=True)
def query_core(A, B, poseA, poseB, margin, warm_a, warm_b, swap, out, scratch):  # type: ignore[no-untyped-def]
    """Exact closest pair of clouds A and B under world poses ``poseA``, ``poseB``.

    Branch and bound over the pair of trees in B's frame: A's node boxes and points are
    mapped by ``inv(poseB) @ poseA`` (A's boxes become the AABBs of the rotated boxes,
    grown by a rounding allowance; mapped lazily, when first reached), node pairs are
    expanded depth first, the nearer child pair first; once A's side is a leaf, each of
    its points (nearest to B's box first) descends B's subtree alone with point-to-box
    bounds (:func:`_descend`). A pair or node is
    pruned when the squared distance between its boxes is not below the best squared
    distance so far. The bound starts at the margin (grown by 1e-9 relative + 1e-12 m,
    so rounding never loses a pair at the margin) or, if smaller, at the distance of the
    warm-start pair (``warm_a``, ``warm_b``: tree-order indices, -1 for none).

    ``A``, ``B``: :class:`TreeArrays`; ``scratch``: a :class:`QueryScratch` for A's
    size. Nothing is allocated. The search is one function on purpose: its loop keeps
    the bound, the stacks and the lazily mapped boxes in registers and locals, and
    numba would pass them through memory at every helper call.

    Writes ``out`` = [distance, point_a xyz, point_b xyz, direction xyz] (world, in the
    caller's order: if ``swap`` the caller's ``a`` is B). Returns ``(status, i, j)``:
    status 0 when a pair within the margin was found, 1 for "no risk" (true distance >
    margin; ``out`` then unset unless ``i >= 0``); ``i``, ``j`` the tree-order indices
    of the A and B points found (-1 for none).
    """
    ptsA, boxA, infoA, cenA = A.points, A.boxes, A.info, A.centroid
    ptsB, boxB, infoB, cenB = B.points, B.boxes, B.info, B.centroid
    tbox, tdone, tp, done = scratch.tbox, scratch.tdone, scratch.tp, scratch.done
    stack_i, stack_g, vec = scratch.stack_i, scratch.stack_g, scratch.vec
    # relative pose: x_B = R x_A + t
    R = np.empty((3, 3))
    t = np.empty(3)
    for i in range(3):
        for j in range(3):
            R[i, j] = (
                poseB[0, i] * poseA[0, j] + poseB[1, i] * poseA[1, j] + poseB[2, i] * poseA[2, j]
            )
        t[i] = (
            poseB[0, i] * (poseA[0, 3] - poseB[0, 3])
            + poseB[1, i] * (poseA[1, 3] - poseB[1, 3])
            + poseB[2, i] * (poseA[2, 3] - poseB[2, 3])
        )
    nA = ptsA.shape[0]
    mA = boxA.shape[0]
    # scale of coordinates, for the rounding allowance on the mapped boxes
    scale = 1.0 + abs(t[0]) + abs(t[1]) + abs(t[2])
    for c in range(3):
        scale += abs(boxA[0, c]) + abs(boxA[0, c + 3])
    pad = 1e-13 * scale
    # A's node boxes in B's frame (AABBs of the mapped boxes), filled lazily: a node's
    # box is mapped when the node is first reached (tdone)
    tdone[:mA] = False
    tdone[0] = True
    k = 0  # the root now; other nodes in pairs of siblings when first reached
    cx = 0.5 * (boxA[k, 0] + boxA[k, 3])
    cy = 0.5 * (boxA[k, 1] + boxA[k, 4])
    cz = 0.5 * (boxA[k, 2] + boxA[k, 5])
    ex = 0.5 * (boxA[k, 3] - boxA[k, 0])
    ey = 0.5 * (boxA[k, 4] - boxA[k, 1])
    ez = 0.5 * (boxA[k, 5] - boxA[k, 2])
    for i in range(3):
        ci = R[i, 0] * cx + R[i, 1] * cy + R[i, 2] * cz + t[i]
        hi = abs(R[i, 0]) * ex + abs(R[i, 1]) * ey + abs(R[i, 2]) * ez + pad
        tbox[k, i] = ci - hi
        tbox[k, i + 3] = ci + hi
    done[:mA] = False  # leaf points of A mapped lazily (into tp)

    if margin == np.inf:
        best2 = np.inf
    else:
        mb = margin * (1.0 + 1e-9) + 1e-12
        best2 = mb * mb
    bi = -1
    bj = -1
    if warm_a >= 0 and warm_a < nA and warm_b >= 0 and warm_b < ptsB.shape[0]:
        d2 = 0.0
        for i in range(3):
            v = (
                R[i, 0] * ptsA[warm_a, 0]
                + R[i, 1] * ptsA[warm_a, 1]
                + R[i, 2] * ptsA[warm_a, 2]
                + t[i]
            ) - ptsB[warm_b, i]
            d2 += v * v
        if d2 <= best2:
            best2 = d2
            bi = warm_a
            bj = warm_b

    lg = stack_g[STACK : STACK + LEAF_MAX]
    lp = stack_i[2 * STACK : 2 * STACK + LEAF_MAX]
    pst = stack_i[2 * STACK + LEAF_MAX : 2 * STACK + LEAF_MAX + POINT_STACK]
    pgs = stack_g[STACK + LEAF_MAX : STACK + LEAF_MAX + POINT_STACK]
    # depth first over node pairs, the nearer child pair first (it tightens the bound
    # quickly); the stack holds each pair with its box distance
    st_a = stack_i[:STACK]
    st_b = stack_i[STACK : 2 * STACK]
    st_g = stack_g[:STACK]
    st_a[0] = 0
    st_b[0] = 0
    st_g[0] = _gap2(tbox, 0, boxB, 0)
    sp = 1
    while sp > 0:
        sp -= 1
        a = st_a[sp]
        b = st_b[sp]
        if st_g[sp] >= best2:
            continue
        ra = infoA[a, 2]
        rb = infoB[b, 2]
        if ra < 0:
            # A is a leaf: each of its points descends B's subtree on its own
            # (point-box bounds are tighter than leaf-box bounds)
            s0 = infoA[a, 0]
            s1 = infoA[a, 1]
            if not done[a]:
                for p in range(s0, s1):
                    for i in range(3):
                        tp[p, i] = (
                            R[i, 0] * ptsA[p, 0]
                            + R[i, 1] * ptsA[p, 1]
                            + R[i, 2] * ptsA[p, 2]
                            + t[i]
                        )
                done[a] = True
            # points nearest to B's box first (insertion sort of at most a leaf)
            m = 0
            for p in range(s0, s1):
                g = _pgap2(tp[p, 0], tp[p, 1], tp[p, 2], boxB, b)
                if g >= best2:
                    continue
                k = m
                while k > 0 and lg[k - 1] > g:
                    lg[k] = lg[k - 1]
                    lp[k] = lp[k - 1]
                    k -= 1
                lg[k] = g
                lp[k] = p
                m += 1
            for k in range(m):
                if lg[k] >= best2:
                    break
                p = lp[k]
                nb2, nbj = _descend(
                    tp[p, 0], tp[p, 1], tp[p, 2], ptsB, boxB, infoB, b, best2, pst, pgs
                )
                if nbj >= 0:
                    best2 = nb2
                    bi = p
                    bj = nbj
            continue
        split_a = True
        if rb >= 0:
            sa = 0.0
            sb = 0.0
            for c in range(3):
                sa += tbox[a, c + 3] - tbox[a, c]
                sb += boxB[b, c + 3] - boxB[b, c]
            split_a = sa >= sb
        if split_a:
            c1 = a + 1
            c2 = ra
            if not tdone[c1]:
                for k in (c1, c2):
                    cx = 0.5 * (boxA[k, 0] + boxA[k, 3])
                    cy = 0.5 * (boxA[k, 1] + boxA[k, 4])
                    cz = 0.5 * (boxA[k, 2] + boxA[k, 5])
                    ex = 0.5 * (boxA[k, 3] - boxA[k, 0])
                    ey = 0.5 * (boxA[k, 4] - boxA[k, 1])
                    ez = 0.5 * (boxA[k, 5] - boxA[k, 2])
                    for i in range(3):
                        ci = R[i, 0] * cx + R[i, 1] * cy + R[i, 2] * cz + t[i]
                        hi = abs(R[i, 0]) * ex + abs(R[i, 1]) * ey + abs(R[i, 2]) * ez + pad
                        tbox[k, i] = ci - hi
                        tbox[k, i + 3] = ci + hi
                tdone[c1] = True
            g1 = _gap2(tbox, c1, boxB, b)
            g2 = _gap2(tbox, c2, boxB, b)
            if g1 > g2:
                c1, c2 = c2, c1
                g1, g2 = g2, g1
            if g2 < best2:
                st_a[sp] = c2
                st_b[sp] = b
                st_g[sp] = g2
                sp += 1
            if g1 < best2:
                st_a[sp] = c1
                st_b[sp] = b
                st_g[sp] = g1
                sp += 1
        else:
            c1 = b + 1
            c2 = rb
            g1 = _gap2(tbox, a, boxB, c1)
            g2 = _gap2(tbox, a, boxB, c2)
            if g1 > g2:
                c1, c2 = c2, c1
                g1, g2 = g2, g1
            if g2 < best2:
                st_a[sp] = a
                st_b[sp] = c2
                st_g[sp] = g2
                sp += 1
            if g1 < best2:
                st_a[sp] = a
                st_b[sp] = c1
                st_g[sp] = g1
                sp += 1

    if bi < 0:
        return 1, -1, -1
    # world points from the caller's (unpermuted) frames: identical values, tree order
    pa = vec[0]
    pb = vec[1]
    ca = vec[2]
    cb = vec[3]
    for i in range(3):
        pa[i] = (
            poseA[i, 0] * ptsA[bi, 0]
            + poseA[i, 1] * ptsA[bi, 1]
            + poseA[i, 2] * ptsA[bi, 2]
            + poseA[i, 3]
        )
        pb[i] = (
            poseB[i, 0] * ptsB[bj, 0]
            + poseB[i, 1] * ptsB[bj, 1]
            + poseB[i, 2] * ptsB[bj, 2]
            + poseB[i, 3]
        )
        ca[i] = poseA[i, 0] * cenA[0] + poseA[i, 1] * cenA[1] + poseA[i, 2] * cenA[2] + poseA[i, 3]
        cb[i] = poseB[i, 0] * cenB[0] + poseB[i, 1] * cenB[1] + poseB[i, 2] * cenB[2] + poseB[i, 3]
    if swap:
        for i in range(3):
            pa[i], pb[i] = pb[i], pa[i]
            ca[i], cb[i] = cb[i], ca[i]
    finish(pa, pb, ca, cb, margin, out)
    if out[0] > margin:
        return 1, bi, bj
    return 0, bi, bj


_SIG_QUERY = types.int64(
    _F2, _F2, _I2, _I1, _F1, _F2, _F2, _I2, _I1, _F1,
    _F2, _F2, types.float64, types.int64, types.int64, types.boolean, _F1, _I1,
)  # fmt: skip


@njit(_SIG_QUERY, cache=True, nogil=True)
def dual_tree_query(  # type: ignore[no-untyped-def]
    ptsA, boxA, infoA, permA, cenA,
    ptsB, boxB, infoB, permB, cenB,
    poseA, poseB, margin, warm_a, warm_b, swap, out, out_idx,
):  # fmt: skip
    """One query of :func:`query_core` with scratch of its own, called from Python.

    Clouds A and B come as the five arrays of a :class:`TreeArrays` each (``points,
    boxes, info, perm, centroid``), not as two named tuples: numba types a named-tuple
    argument in Python at every call (≈ 2.5 µs each, measured, against ≈ 5 µs for a
    whole query of far-apart clouds), flat arrays through its C fast path. Inside, the
    arrays are grouped for :func:`query_core` at no cost.

    Writes ``out`` (see :func:`query_core`) and ``out_idx`` = [input row of the A
    point, input row of the B point, their tree-order indices] (-1 when none was
    found); returns the status (0 within the margin, 1 "no risk").
    """
    if out.shape[0] < 10 or out_idx.shape[0] < 4:  # the kernel writes without bounds checks
        raise ValueError("dual_tree_query: out needs 10 entries and out_idx 4")
    mA = boxA.shape[0]
    scratch = QueryScratch(
        np.empty((mA, 6)),
        np.empty(mA, np.bool_),
        np.empty((ptsA.shape[0], 3)),
        np.empty(mA, np.bool_),
        np.empty(STACK_INTS, np.int64),
        np.empty(STACK_FLOATS),
        np.empty((4, 3)),
    )
    A = TreeArrays(ptsA, boxA, infoA, permA, cenA)
    B = TreeArrays(ptsB, boxB, infoB, permB, cenB)
    status, bi, bj = query_core(A, B, poseA, poseB, margin, warm_a, warm_b, swap, out, scratch)
    out_idx[0] = permA[bi] if bi >= 0 else -1
    out_idx[1] = permB[bj] if bj >= 0 else -1
    out_idx[2] = bi
    out_idx[3] = bj
    return status
