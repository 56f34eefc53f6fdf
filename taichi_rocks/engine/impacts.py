"""Stones against vehicle bodies: the swept sphere-hull test, the response, and the damage class (Taichi funcs).

Everything here takes plain vectors and matrices (no World fields), in the vehicle's moving frame: a stone of
radius r whose centre goes from p0 (body frame at the step's start) to p1 (body frame at the step's end)
against one convex part, a hexahedron given by its 6 outward face planes (n_k . x <= d_k inside) and its 8
corners (motion/bodies.py: ``hexahedron_planes``, ``Part.corners``; boxes are hexahedra too).

Swept test (Ericson, Real-Time Collision Detection, 2005, 5.5.7). The set the centre must not enter is the part
dilated by r: faces pushed out by r, joined by cylinders round the edges and spheres round the corners. The
path p(t) = p0 + t (p1 - p0), t in [0, 1], is clipped against the 6 planes pushed out by r (a convex set that
holds the dilated part). A path that misses it misses the part (12 dot products: the common case). If it
enters from outside through plane k at t_in and the foot q - r n_k lies on face k, that is the contact.
Otherwise the contact is on an edge cylinder (first root of |(m + t d) x e|^2 = r^2 whose foot lies within the
edge) or a corner sphere (|m + t d|^2 = r^2), whichever comes first: every such root is a time of contact, and the first contact lies on one of them, so
the earliest is exact. These roots are solved from the entry point on (no contact comes before it, and it lies
within ~2 r of the contact, which keeps them precise in float32) as c / (-b + sqrt(b^2 - a c)), free of
cancellation; a feature the entry point is already within r of (up to rounding) is touched there. A stone that
starts within r of the part (exact distance: the feet on faces and the closest points of edges) or inside it
counts at t = 0 (only a path that starts within the pushed-out planes can). No seam opens between neighbouring pieces through rounding: an edge's cylinder is taken
wherever its foot lies on the edge, beyond the edge's own share of the dilated part, and a corner's sphere
everywhere, so a contact a face test rejects by a rounding error is found on its edge, and one an edge rejects
at its end on the corner.

Response (the contact's moving frame): u = v_rock - v_body(contact), v_body(c) = v_centre + yaw_rate z x c
(planar rigid motion); u_n = u . n reflects to -e u_n, the tangential part loses the Coulomb impulse
mu (1 + e) |u_n|, never more than stops it (as the ground bounce of engine/flight.py). Only an approaching
stone (u_n < 0) is changed.

Damage class from the normal component: 0 mark below ``chip``, 1 chip below ``crack``, 2 crack (thresholds from
the scene's [impacts] table, config/impacts.py, in J of normal energy 1/2 m u_n^2 or N s of normal momentum
m |u_n|; they are proxies, see there).
"""

import taichi as ti

from ..motion.bodies import EDGES

# The loops over faces, edges and corners are runtime loops over small constant tables, not unrolled: inlined
# unrolled, the test made a kernel take ~30 s more to compile; the results are the same operations in the
# same order.
_EDGE_TABLE = ti.Matrix(EDGES, ti.i32)

__all__ = ["swept_sphere_hull", "surface_velocity", "bounce", "damage_class", "stone_mass"]


@ti.func
def _plane(planes: ti.template(), k):
    return ti.Vector([planes[k, 0], planes[k, 1], planes[k, 2]]), planes[k, 3]


@ti.func
def _corner(corners: ti.template(), i):
    return ti.Vector([corners[i, 0], corners[i, 1], corners[i, 2]])


@ti.func
def _entry(a, b, c):
    """The entering root t >= 0 of a t^2 + 2 b t + c = 0 (c: the start's squared distance minus r^2): 0 for
    a start already within (c <= 0: at the entry point, which lies on the dilated part up to rounding),
    else the first root of a path that closes in (b < 0); -1 when there is none."""
    t = c * 0.0 - 1.0
    disc = b * b - a * c
    if c <= 0.0:
        t = c * 0.0
    elif b < 0.0 and disc >= 0.0:
        t = c / (-b + ti.sqrt(disc))
    return t


@ti.func
def _on_face(planes: ti.template(), k, x):
    """x (on the plane of face k) is within face k: inside every other face's plane."""
    ok = True
    for j in range(6):
        if j != k:
            n, d = _plane(planes, j)
            if n.dot(x) > d:
                ok = False
    return ok


@ti.func
def _edge_closest(corners: ti.template(), a, b, p):
    """The point of edge (a, b) closest to p."""
    v0 = _corner(corners, a)
    e = _corner(corners, b) - v0
    ee = e.dot(e)
    s = ee * 0.0
    if ee > 0.0:
        s = ti.min(ti.max((p - v0).dot(e) / ee, 0.0), 1.0)
    return v0 + s * e


@ti.func
def _start_contact(p0, r, planes: ti.template(), corners: ti.template()):
    """Whether a stone at p0 touches the part (distance <= r, or inside), with the closest point and the
    outward normal there; inside: the face of least depth."""
    hit = 0
    point = p0
    normal = p0 * 0.0
    deepest = p0[0] * 0.0 - 1e30
    inside = True
    for k in range(6):
        n, d = _plane(planes, k)
        s = n.dot(p0) - d
        if s > 0.0:
            inside = False
        if s > deepest:
            deepest, normal, point = s, n, p0 - s * n
    if inside:
        hit = 1
    else:
        best = r * r
        for k in range(6):
            n, d = _plane(planes, k)
            s = n.dot(p0) - d
            if s > 0.0 and s * s <= best:
                if _on_face(planes, k, p0 - s * n):
                    best, hit, point, normal = s * s, 1, p0 - s * n, n
        for j in range(12):
            q = _edge_closest(corners, _EDGE_TABLE[j, 0], _EDGE_TABLE[j, 1], p0)
            dq = p0 - q
            dd = dq.dot(dq)
            if dd <= best and dd > 0.0:
                best, hit, point, normal = dd, 1, q, dq / ti.sqrt(dd)
    return hit, point, normal


@ti.func
def _edges_and_corners(p0, d, r, corners: ti.template()):
    """The first contact of the path p0 + t d, t >= 0, with an edge cylinder or a corner sphere: t (> 1 when
    none), the closest point of the part and the outward normal there."""
    t_best = r * 0.0 + 2.0
    point = p0
    normal = p0 * 0.0
    rr = r * r
    for j in range(12):
        v0 = _corner(corners, _EDGE_TABLE[j, 0])
        ev = _corner(corners, _EDGE_TABLE[j, 1]) - v0
        length = ev.norm()
        if length > 0.0:
            e = ev / length
            m = p0 - v0
            m_perp = m - m.dot(e) * e
            d_perp = d - d.dot(e) * e
            t = _entry(d_perp.dot(d_perp), m_perp.dot(d_perp), m_perp.dot(m_perp) - rr)
            if 0.0 <= t and t < t_best:
                s = (m + t * d).dot(e)
                if 0.0 <= s and s <= length:
                    foot = v0 + s * e
                    t_best, point, normal = t, foot, (m_perp + t * d_perp).normalized()
    for i in range(8):
        v = _corner(corners, i)
        m = p0 - v
        t = _entry(d.dot(d), m.dot(d), m.dot(m) - rr)
        if 0.0 <= t and t < t_best:
            t_best, point, normal = t, v, (m + t * d).normalized()
    return t_best, point, normal


@ti.func
def _face_of(planes: ti.template(), normal):
    """The face whose outward normal is closest to ``normal``."""
    face = 0
    best = normal[0] * 0.0 - 2.0
    for k in range(6):
        n, _ = _plane(planes, k)
        c = n.dot(normal)
        if c > best:
            best, face = c, k
    return face


@ti.func
def swept_sphere_hull(p0, p1, r, planes: ti.template(), corners: ti.template()):
    """First contact in [0, 1] of a sphere of radius r moving from p0 to p1 with a convex hexahedron (planes:
    6 x 4 outward (n, d); corners: 8 x 3). Returns (hit, t, point, normal, face): hit 1 or 0; t the fraction of
    the move; point the part's surface point touched; normal the outward unit normal there (the direction from
    it to the centre at contact); face the part's face the normal leans to."""
    d = p1 - p0
    hit = 0
    t = r * 0.0
    point = p0
    normal = p0 * 0.0
    # clip the path against the planes pushed out by r: nearly every path that misses stops here
    t_in, t_out = r * 0.0, r * 0.0 + 1.0
    k_in = -1
    for k in range(6):
        n, off = _plane(planes, k)
        s = n.dot(p0) - off - r
        dn = n.dot(d)
        if dn < 0.0:
            tk = s / -dn
            if tk > t_in:
                t_in, k_in = tk, k
        elif dn > 0.0:
            t_out = ti.min(t_out, -s / dn)
        elif s > 0.0:
            t_out = -r - 1.0  # parallel to the plane and outside it
    if t_in <= t_out:
        if k_in < 0:  # starts within the pushed-out planes: it may touch already
            hit, point, normal = _start_contact(p0, r, planes, corners)
        if hit == 0:
            done = 0
            if k_in >= 0:
                n, _ = _plane(planes, k_in)
                foot = p0 + t_in * d - r * n
                if _on_face(planes, k_in, foot):
                    hit, t, point, normal, done = 1, t_in, foot, n, 1
            if done == 0:  # from the entry point on: it is within ~2 r of the contact, the roots stay precise
                tc, pc, nc = _edges_and_corners(p0 + t_in * d, d, r, corners)
                if t_in + tc <= 1.0:
                    hit, t, point, normal = 1, t_in + tc, pc, nc
    face = _face_of(planes, normal)
    return hit, t, point, normal, face


@ti.func
def surface_velocity(v_centre, yaw_rate, arm):
    """Velocity of the body's point at ``arm`` from its centre (world axes): v_centre + yaw_rate z x arm."""
    return v_centre + yaw_rate * ti.Vector([-arm[1], arm[0], 0.0 * arm[2]])


@ti.func
def bounce(v, v_surface, n, restitution, friction):
    """A stone of velocity v on a surface moving at v_surface with outward normal n: the new velocity and the
    normal relative speed before (u . n; < 0 closing). A stone that does not close in keeps its velocity."""
    u = v - v_surface
    un = u.dot(n)
    out = v
    if un < 0.0:
        ut = u - un * n
        ut_norm = ut.norm()
        loss = friction * (1.0 + restitution) * -un
        keep = ut_norm * 0.0
        if ut_norm > loss:
            keep = (ut_norm - loss) / ut_norm
        out = v_surface + keep * ut - restitution * un * n
    return out, un


@ti.func
def stone_mass(radius, mass_per_r3):
    """m = (4/3 pi rho) r^3 (kg): ``mass_per_r3`` = 4/3 pi rho comes from the host in the simulation's precision
    (a float literal in a kernel would be float32, 3e-8 off in a float64 run)."""
    return mass_per_r3 * radius * radius * radius


@ti.func
def damage_class(value, chip, crack):
    """0 (mark) for value < chip, 1 (chip) for value < crack, else 2 (crack)."""
    c = 0
    if value >= crack:
        c = 2
    elif value >= chip:
        c = 1
    return c
