"""Compiled contact geometry: the gap, normal and contact points of every contact feature.

A *feature* is one point contact that a pair of shapes can have: the sphere of a
sphere-plane pair, each of the 8 vertices of a box against a plane, each end sphere of a
capsule, each rim of a cylinder, the closest points of two spheres, of a sphere and a box, of
a capsule's axis and a sphere, each vertex of one box against the faces of another. For
the state (x, D) of the bodies, a feature gives

    gap   the signed distance between the two surfaces along the normal (m; < 0 overlap),
    n     the unit normal, pointing from body b (or the plane) to body a,
    ra    the contact point on a relative to a's centre of mass (world),
    rb    the contact point on b relative to b's centre of mass (world; unused for planes),

with the property the scheme relies on: for velocities (v, w) of the bodies, the rate of the
gap is n . ((v_a + w_a x ra) - (v_b + w_b x rb)) (the velocity of a's material point at the
contact relative to b's), exactly. The rows of the contact problem are this relative velocity
along n and two tangents.

Each feature is exact for its pair (the true distance between the rigid shapes), except
where flagged ``inexact``: a cylinder standing on its flat face (a disk contact), a sphere's
centre inside a box, and box-box configurations whose contact polygon has a vertex that is
no vertex of either box (edge-edge contact, crossing faces; :func:`box_pair_check`). The
kernel stops with a clear status there rather than approximate.

Layout (float64 / int64 arrays built by director_model.contact.scene):

``FI`` (nfeat, 4): kind, body a, body b (-1 for a plane), pair index.
``FV`` (nfeat, 10): parameters, by kind:
    K_PLANE_SPHERE   n (3), offset c, radius r
    K_PLANE_VERTEX   n, c, vertex xi (3, body frame of a)
    K_PLANE_CAPSULE  n, c, radius, s (the end at s e_3, s = +-half_length)
    K_PLANE_RIM      n, c, radius, s (the rim centred at s e_3)
    K_SPHERE_SPHERE  r_a, r_b
    K_SPHERE_BOX     r_a, half extents of b (3)
    K_CAPSULE_SPHERE r_a, half_length of a, r_b
    K_BOX_VERTEX     vertex xi of a (3), half extents of b (3), 1 if a is the pair's second
                     box (its vertices on a corner of the first box are left to the first's)
"""

from __future__ import annotations

import math

from numba import njit

K_PLANE_SPHERE = 0
K_PLANE_VERTEX = 1
K_PLANE_CAPSULE = 2
K_PLANE_RIM = 3
K_SPHERE_SPHERE = 4
K_SPHERE_BOX = 5
K_CAPSULE_SPHERE = 6
K_BOX_VERTEX = 7

#: a cylinder whose axis is within this sine of a plane's normal stands on a flat face: the
#: contact is a disk, refused (inexact) when it is within the candidate margin
RIM_UPRIGHT = 1e-9
#: relative tolerance of "inside a face's extent" for box vertices (a vertex on an edge or a
#: corner of the other box's face counts as on the face)
EXTENT_TOL = 1e-9


@njit(inline="always")
def _dot(a0, a1, a2, b0, b1, b2):
    return a0 * b0 + a1 * b1 + a2 * b2


@njit(inline="always")
def body_point(X, D, i, x0, x1, x2):
    """D_i xi (world offset of the body-frame point xi of body i); D (nb, 9) row-major."""
    return (
        D[i, 0] * x0 + D[i, 1] * x1 + D[i, 2] * x2,
        D[i, 3] * x0 + D[i, 4] * x1 + D[i, 5] * x2,
        D[i, 6] * x0 + D[i, 7] * x1 + D[i, 8] * x2,
    )


@njit(inline="always")
def to_body(D, i, y0, y1, y2):
    """D_i^T y (a world vector in the axes of body i)."""
    return (
        D[i, 0] * y0 + D[i, 3] * y1 + D[i, 6] * y2,
        D[i, 1] * y0 + D[i, 4] * y1 + D[i, 7] * y2,
        D[i, 2] * y0 + D[i, 5] * y1 + D[i, 8] * y2,
    )


@njit(inline="always")
def feature(FI, FV, k, X, D):
    """The feature k at the state X (nb, 3), D (nb, 9). Returns (valid, inexact, gap, n0, n1,
    n2, ra0, ra1, ra2, rb0, rb1, rb2, dist): ``valid`` False if the feature does not exist in
    this configuration (a box vertex beyond the other box's face); ``dist`` a lower bound of
    the distance between the two shapes near this feature (for the candidate test)."""
    kind = FI[k, 0]
    a = FI[k, 1]
    b = FI[k, 2]
    z = 0.0
    if kind == K_PLANE_SPHERE:
        n0, n1, n2, c, r = FV[k, 0], FV[k, 1], FV[k, 2], FV[k, 3], FV[k, 4]
        gap = _dot(n0, n1, n2, X[a, 0], X[a, 1], X[a, 2]) - c - r
        return True, False, gap, n0, n1, n2, -r * n0, -r * n1, -r * n2, z, z, z, gap
    if kind == K_PLANE_VERTEX:
        n0, n1, n2, c = FV[k, 0], FV[k, 1], FV[k, 2], FV[k, 3]
        r0, r1, r2 = body_point(X, D, a, FV[k, 4], FV[k, 5], FV[k, 6])
        gap = _dot(n0, n1, n2, X[a, 0] + r0, X[a, 1] + r1, X[a, 2] + r2) - c
        return True, False, gap, n0, n1, n2, r0, r1, r2, z, z, z, gap
    if kind == K_PLANE_CAPSULE:
        n0, n1, n2, c, r, s = FV[k, 0], FV[k, 1], FV[k, 2], FV[k, 3], FV[k, 4], FV[k, 5]
        e0, e1, e2 = D[a, 2] * s, D[a, 5] * s, D[a, 8] * s
        gap = _dot(n0, n1, n2, X[a, 0] + e0, X[a, 1] + e1, X[a, 2] + e2) - c - r
        return True, False, gap, n0, n1, n2, e0 - r * n0, e1 - r * n1, e2 - r * n2, z, z, z, gap
    if kind == K_PLANE_RIM:
        n0, n1, n2, c, R, s = FV[k, 0], FV[k, 1], FV[k, 2], FV[k, 3], FV[k, 4], FV[k, 5]
        a0, a1, a2 = D[a, 2], D[a, 5], D[a, 8]  # the axis d_3
        e0, e1, e2 = a0 * s, a1 * s, a2 * s
        na = _dot(n0, n1, n2, a0, a1, a2)
        p0, p1, p2 = n0 - na * a0, n1 - na * a1, n2 - na * a2  # n projected off the axis
        pn = math.sqrt(_dot(p0, p1, p2, p0, p1, p2))
        base = _dot(n0, n1, n2, X[a, 0] + e0, X[a, 1] + e1, X[a, 2] + e2) - c
        if not pn > RIM_UPRIGHT:
            # standing on the flat face: every rim point is lowest (a disk contact)
            return True, True, base, n0, n1, n2, e0, e1, e2, z, z, z, base - R
        u0, u1, u2 = -p0 / pn, -p1 / pn, -p2 / pn  # rim direction to the lowest point
        gap = base - R * pn
        return True, False, gap, n0, n1, n2, e0 + R * u0, e1 + R * u1, e2 + R * u2, z, z, z, gap
    if kind == K_SPHERE_SPHERE:
        ra, rb = FV[k, 0], FV[k, 1]
        d0, d1, d2 = X[a, 0] - X[b, 0], X[a, 1] - X[b, 1], X[a, 2] - X[b, 2]
        L = math.sqrt(_dot(d0, d1, d2, d0, d1, d2))
        if not L > 0.0:
            return True, True, -ra - rb, 0.0, 0.0, 1.0, z, z, z, z, z, z, -ra - rb
        n0, n1, n2 = d0 / L, d1 / L, d2 / L
        gap = L - ra - rb
        return (
            True,
            False,
            gap,
            n0,
            n1,
            n2,
            -ra * n0,
            -ra * n1,
            -ra * n2,
            rb * n0,
            rb * n1,
            rb * n2,
            gap,
        )
    if kind == K_SPHERE_BOX:
        r, h0, h1, h2 = FV[k, 0], FV[k, 1], FV[k, 2], FV[k, 3]
        y0, y1, y2 = to_body(D, b, X[a, 0] - X[b, 0], X[a, 1] - X[b, 1], X[a, 2] - X[b, 2])
        c0, c1, c2 = min(max(y0, -h0), h0), min(max(y1, -h1), h1), min(max(y2, -h2), h2)
        q0, q1, q2 = body_point(X, D, b, c0, c1, c2)  # closest point of the box, rel. x_b
        d0, d1, d2 = X[a, 0] - X[b, 0] - q0, X[a, 1] - X[b, 1] - q1, X[a, 2] - X[b, 2] - q2
        L = math.sqrt(_dot(d0, d1, d2, d0, d1, d2))
        if not L > 0.0:
            # the sphere's centre is inside the box: no defined normal
            return True, True, -r, 0.0, 0.0, 1.0, z, z, z, q0, q1, q2, -r
        n0, n1, n2 = d0 / L, d1 / L, d2 / L
        gap = L - r
        return True, False, gap, n0, n1, n2, -r * n0, -r * n1, -r * n2, q0, q1, q2, gap
    if kind == K_CAPSULE_SPHERE:
        ra, hl, rb = FV[k, 0], FV[k, 1], FV[k, 2]
        t = _dot(D[a, 2], D[a, 5], D[a, 8], X[b, 0] - X[a, 0], X[b, 1] - X[a, 1], X[b, 2] - X[a, 2])
        t = min(max(t, -hl), hl)
        s0, s1, s2 = D[a, 2] * t, D[a, 5] * t, D[a, 8] * t  # axis point rel. x_a
        d0, d1, d2 = X[a, 0] + s0 - X[b, 0], X[a, 1] + s1 - X[b, 1], X[a, 2] + s2 - X[b, 2]
        L = math.sqrt(_dot(d0, d1, d2, d0, d1, d2))
        if not L > 0.0:
            return True, True, -ra - rb, 0.0, 0.0, 1.0, z, z, z, z, z, z, -ra - rb
        n0, n1, n2 = d0 / L, d1 / L, d2 / L
        gap = L - ra - rb
        return (True, False, gap, n0, n1, n2, s0 - ra * n0, s1 - ra * n1, s2 - ra * n2,
                rb * n0, rb * n1, rb * n2, gap)  # fmt: skip
    # K_BOX_VERTEX: vertex xi of box a against the faces of box b
    r0, r1, r2 = body_point(X, D, a, FV[k, 0], FV[k, 1], FV[k, 2])
    w0, w1, w2 = X[a, 0] + r0 - X[b, 0], X[a, 1] + r1 - X[b, 1], X[a, 2] + r2 - X[b, 2]
    y0, y1, y2 = to_body(D, b, w0, w1, w2)
    h0, h1, h2 = FV[k, 3], FV[k, 4], FV[k, 5]
    s0, s1, s2 = abs(y0) - h0, abs(y1) - h1, abs(y2) - h2
    # the face of b the vertex is over: the axis of largest excess (the box's distance
    # function is max(s) inside and on the faces' outer slabs)
    j = 0
    sj = s0
    if s1 > sj:
        j = 1
        sj = s1
    if s2 > sj:
        j = 2
        sj = s2
    tol = EXTENT_TOL * (h0 + h1 + h2)
    ties = (
        (1 if s0 >= sj - tol else 0) + (1 if s1 >= sj - tol else 0) + (1 if s2 >= sj - tol else 0)
    )
    if ties > 1:
        # the vertex is on an edge or a corner of b (two equal boxes stacked face on face
        # put every vertex there): the face of b that faces a's centre, the axis along which
        # a's centre lies farthest beyond b's extent
        c0, c1, c2 = to_body(D, b, X[a, 0] - X[b, 0], X[a, 1] - X[b, 1], X[a, 2] - X[b, 2])
        best = -math.inf
        for q in range(3):
            sk = s0 if q == 0 else (s1 if q == 1 else s2)
            if sk >= sj - tol:
                ck = c0 if q == 0 else (c1 if q == 1 else c2)
                hk = h0 if q == 0 else (h1 if q == 1 else h2)
                if abs(ck) - hk > best:
                    best = abs(ck) - hk
                    j = q
        sj = s0 if j == 0 else (s1 if j == 1 else s2)
    o0 = max(s0, 0.0) if j != 0 else 0.0
    o1 = max(s1, 0.0) if j != 1 else 0.0
    o2 = max(s2, 0.0) if j != 2 else 0.0
    valid = o0 <= tol and o1 <= tol and o2 <= tol
    if ties == 3 and FV[k, 6] != 0.0:
        # a vertex of the pair's second box on a corner of the first: the same point as
        # that corner's own feature against the second box's face (kept); one row per point
        valid = False
    yj = y0 if j == 0 else (y1 if j == 1 else y2)
    sg = 1.0 if yj >= 0.0 else -1.0
    n0, n1, n2 = D[b, j] * sg, D[b, 3 + j] * sg, D[b, 6 + j] * sg
    # Euclidean distance to the box when outside (lower bound of the surfaces' distance)
    dist = math.sqrt(max(s0, 0.0) ** 2 + max(s1, 0.0) ** 2 + max(s2, 0.0) ** 2)
    if sj <= 0.0:
        dist = sj
    return valid, False, sj, n0, n1, n2, r0, r1, r2, w0, w1, w2, dist


@njit(_nrt=False)
def eval_features(FI, FV, idx, n, X, D, out):
    """:func:`feature` for the features idx[0:n] into out[k] = (valid, inexact, gap, n (3),
    ra (3), rb (3), dist): one compiled copy of the feature code, called once per batch of
    features (its call costs less than the features it evaluates)."""
    for k in range(n):
        valid, inexact, gap, n0, n1, n2, ra0, ra1, ra2, rb0, rb1, rb2, dist = feature(
            FI, FV, idx[k], X, D
        )
        out[k, 0] = 1.0 if valid else 0.0
        out[k, 1] = 1.0 if inexact else 0.0
        out[k, 2] = gap
        out[k, 3] = n0
        out[k, 4] = n1
        out[k, 5] = n2
        out[k, 6] = ra0
        out[k, 7] = ra1
        out[k, 8] = ra2
        out[k, 9] = rb0
        out[k, 10] = rb1
        out[k, 11] = rb2
        out[k, 12] = dist


@njit(inline="always")
def _box_axes(X, D, a, b, ha, hb):
    """Separating-axis test of boxes a and b (half extents ha, hb as 3-tuples) in the frame
    of box a (Gottschalk, Lin & Manocha 1996): with C = D_a^T D_b (C[i][j] = a_i . b_j) and
    T = D_a^T (x_a - x_b), the separation along each of the 15 axes (the 6 face normals and
    the 9 edge cross products a_i x b_j) is |T . L| - (support of a) - (support of b) over
    |L|, every term a product of entries of C and T (no axis is formed or normalised).
    Returns (largest separation, its axis (0-2: a's faces, 3-5: b's faces, 6: an edge
    pair), largest separation along a face axis, that face axis). Parallel edges
    (|a_i x b_j| < 1e-6) are skipped: their axis is a face axis."""
    t0 = X[a, 0] - X[b, 0]
    t1 = X[a, 1] - X[b, 1]
    t2 = X[a, 2] - X[b, 2]
    T = (_dot(D[a, 0], D[a, 3], D[a, 6], t0, t1, t2),
         _dot(D[a, 1], D[a, 4], D[a, 7], t0, t1, t2),
         _dot(D[a, 2], D[a, 5], D[a, 8], t0, t1, t2))  # fmt: skip
    C = (
        _dot(D[a, 0], D[a, 3], D[a, 6], D[b, 0], D[b, 3], D[b, 6]),
        _dot(D[a, 0], D[a, 3], D[a, 6], D[b, 1], D[b, 4], D[b, 7]),
        _dot(D[a, 0], D[a, 3], D[a, 6], D[b, 2], D[b, 5], D[b, 8]),
        _dot(D[a, 1], D[a, 4], D[a, 7], D[b, 0], D[b, 3], D[b, 6]),
        _dot(D[a, 1], D[a, 4], D[a, 7], D[b, 1], D[b, 4], D[b, 7]),
        _dot(D[a, 1], D[a, 4], D[a, 7], D[b, 2], D[b, 5], D[b, 8]),
        _dot(D[a, 2], D[a, 5], D[a, 8], D[b, 0], D[b, 3], D[b, 6]),
        _dot(D[a, 2], D[a, 5], D[a, 8], D[b, 1], D[b, 4], D[b, 7]),
        _dot(D[a, 2], D[a, 5], D[a, 8], D[b, 2], D[b, 5], D[b, 8]),
    )
    best = -math.inf
    bestk = -1
    for i in range(3):  # a's faces: support of a is ha_i
        s = abs(T[i]) - ha[i] - (hb[0] * abs(C[3 * i]) + hb[1] * abs(C[3 * i + 1])
                                 + hb[2] * abs(C[3 * i + 2]))  # fmt: skip
        if s > best:
            best = s
            bestk = i
    for j in range(3):  # b's faces
        tb = _dot(D[b, j], D[b, 3 + j], D[b, 6 + j], t0, t1, t2)
        s = abs(tb) - hb[j] - (ha[0] * abs(C[j]) + ha[1] * abs(C[3 + j])
                               + ha[2] * abs(C[6 + j]))  # fmt: skip
        if s > best:
            best = s
            bestk = 3 + j
    bestf = best
    bestkf = bestk
    for i in range(3):
        i1 = (i + 1) % 3
        i2 = (i + 2) % 3
        for j in range(3):
            j1 = (j + 1) % 3
            j2 = (j + 2) % 3
            # L = a_i x b_j = C[i1][j] a_i2 - C[i2][j] a_i1 in a's frame
            p = C[3 * i1 + j]
            q = C[3 * i2 + j]
            ln = math.sqrt(p * p + q * q)
            if ln < 1e-6:
                continue
            ra = ha[i1] * abs(q) + ha[i2] * abs(p)
            rb = hb[j1] * abs(C[3 * i + j2]) + hb[j2] * abs(C[3 * i + j1])
            s = (abs(p * T[i2] - q * T[i1]) - ra - rb) / ln
            if s > best:
                best = s
                bestk = 6
    return best, bestk, bestf, bestkf


@njit(inline="always")
def box_pair_check(X, D, a, b, ha, hb, margin, P):
    """Whether the contact of boxes a and b (half extents ha, hb) within ``margin`` is
    treated exactly by their vertex features. Returns (near, exact): ``near`` False if the
    boxes are farther apart than margin along some axis (no contact this step). ``P`` (8, 4)
    scratch.

    Separating-axis test (:func:`_box_axes`: the 6 face normals and the 9 cross products of
    edges). The contact is exact when its region's corners are vertices of the
    boxes: refused (exact False) when the largest separation is along an edge-edge axis
    (an edge touching an edge), or, on a face axis, when the incident box's vertices lying
    in the contact plane leave the reference face (a vertex or edge over the face's border)
    and, for two faces in contact, when their clipped overlap has a corner that is neither
    box's vertex (crossing edges)."""
    best, bestk, bestf, bestkf = _box_axes(X, D, a, b, ha, hb)
    if best > margin:
        return False, True
    scale = ha[0] + ha[1] + ha[2] + hb[0] + hb[1] + hb[2]
    if bestk == 6 and best > bestf + 1e-9 * scale:
        return True, False
    # reference face (the best face axis): of box r, axis j, outward sign towards the
    # incident box i
    r = a if bestkf < 3 else b
    i = b if bestkf < 3 else a
    j = bestkf % 3
    hr = ha if r == a else hb
    hi = hb if r == a else ha
    dj = _dot(
        D[r, j], D[r, 3 + j], D[r, 6 + j], X[i, 0] - X[r, 0], X[i, 1] - X[r, 1], X[i, 2] - X[r, 2]
    )
    sg = 1.0 if dj >= 0.0 else -1.0
    n0, n1, n2 = D[r, j] * sg, D[r, 3 + j] * sg, D[r, 6 + j] * sg
    # in-plane axes of the reference face and its half extents along them
    j1 = (j + 1) % 3
    j2 = (j + 2) % 3
    e1 = hr[j1]
    e2 = hr[j2]
    tol = EXTENT_TOL * scale
    # incident vertices in the contact plane (within margin of the lowest one)
    hmin = math.inf
    for v in range(8):
        x0 = hi[0] if v & 1 else -hi[0]
        x1 = hi[1] if v & 2 else -hi[1]
        x2 = hi[2] if v & 4 else -hi[2]
        p0, p1, p2 = body_point(X, D, i, x0, x1, x2)
        hgt = _dot(
            n0, n1, n2, p0 + X[i, 0] - X[r, 0], p1 + X[i, 1] - X[r, 1], p2 + X[i, 2] - X[r, 2]
        )
        hmin = min(hmin, hgt)
    np_ = 0
    for v in range(8):
        x0 = hi[0] if v & 1 else -hi[0]
        x1 = hi[1] if v & 2 else -hi[1]
        x2 = hi[2] if v & 4 else -hi[2]
        p0, p1, p2 = body_point(X, D, i, x0, x1, x2)
        w0, w1, w2 = p0 + X[i, 0] - X[r, 0], p1 + X[i, 1] - X[r, 1], p2 + X[i, 2] - X[r, 2]
        hgt = _dot(n0, n1, n2, w0, w1, w2)
        if hgt <= hmin + margin + tol:
            P[np_, 0] = _dot(D[r, j1], D[r, 3 + j1], D[r, 6 + j1], w0, w1, w2)
            P[np_, 1] = _dot(D[r, j2], D[r, 3 + j2], D[r, 6 + j2], w0, w1, w2)
            np_ += 1
    inside = 0
    for m in range(np_):
        if abs(P[m, 0]) <= e1 + tol and abs(P[m, 1]) <= e2 + tol:
            inside += 1
    if inside == np_:
        return True, True  # the incident vertex, edge or face lies on the reference face
    if np_ != 4:
        return True, False  # a vertex or an edge of the incident box over the face's border
    # two faces in contact: order the incident face's 4 vertices around their centroid
    cx = 0.25 * (P[0, 0] + P[1, 0] + P[2, 0] + P[3, 0])
    cy = 0.25 * (P[0, 1] + P[1, 1] + P[2, 1] + P[3, 1])
    for m in range(4):
        P[m, 2] = math.atan2(P[m, 1] - cy, P[m, 0] - cx)
        P[m, 3] = m
    for p in range(4):
        for q in range(3 - p):
            if P[int(P[q, 3]), 2] > P[int(P[q + 1, 3]), 2]:
                t = P[q, 3]
                P[q, 3] = P[q + 1, 3]
                P[q + 1, 3] = t
    # every corner of (incident face) intersect (reference rectangle) must be a vertex of one
    # of them: no edge of the incident face may cross the rectangle's border between its
    # corners
    for m in range(4):
        ia = int(P[m, 3])
        ib = int(P[(m + 1) % 4, 3])
        A0, A1 = P[ia, 0], P[ia, 1]
        B0, B1 = P[ib, 0], P[ib, 1]
        for side in range(4):
            # rectangle side: coordinate c (0: x, 1: y) equal to +-e, the other within +-e'
            c = side // 2
            sgn = 1.0 if side % 2 == 0 else -1.0
            lim = (e1 if c == 0 else e2) * sgn
            oth = e2 if c == 0 else e1
            a_c = A0 if c == 0 else A1
            b_c = B0 if c == 0 else B1
            if (a_c - lim) * (b_c - lim) < 0.0:
                t = (lim - a_c) / (b_c - a_c)
                a_o = A1 if c == 0 else A0
                b_o = B1 if c == 0 else B0
                o = a_o + t * (b_o - a_o)
                # a crossing strictly inside the side (not at the rectangle's corner)
                if abs(o) < oth - tol:
                    return True, False
    return True, True
