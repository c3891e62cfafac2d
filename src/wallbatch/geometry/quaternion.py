"""Ellipsoid mathematics: quaternions, inertia and the nve/asphere rotation step (the wall/ees
ellipsoid-wall interaction is in wallbatch.styles.ees) (physics.md §4.7, §6, §11.2, §11.3).

Everything is batched over arbitrary leading axes: quaternions are ``(..., 4)`` arrays
``(w, i, j, k)``, semi-axes ``(..., 3)``, angular momenta and normals ``(..., 3)``, scalars
``(...)``; leading axes broadcast (e.g. ``(C, N, 4)`` quaternions with ``(C, N, 3)`` shapes).

Conventions (§11.3): ``A = rotation_matrix(q)`` maps body to space, its columns are the body
axes in the space frame. ``shape`` holds the semi-axes (a, b, c) (LAMMPS's ``set shape`` and
data-file ``Ellipsoids`` section take *diameters*). Angular momentum ``L`` is in the space frame.

wall/ees (§4.7): with r the distance of the centre from the wall and sigma_n the distance from the
centre to the tangent plane parallel to the wall (:func:`sigma_n`),

    E = eps [ 2 sigma^12 (7r^5 + 14r^3 sn^2 + 3r sn^4) / (945 h^7)
              - sigma^6 (2r sn^3 + sn^2 h ln((r - sn)/(r + sn))) / (12 sn^5 h) ],   h = r^2 - sn^2

is exactly the 12-6 Lennard-Jones energy integrated over the ellipsoid volume and the wall
half-space, 4 eps_LJ rho_e rho_w \\int\\int [(s/d)^12 - (s/d)^6], with
``eps = 8 pi^2 rho_wall rho_ellipsoid eps_LJ a b c`` (a, b, c the semi-axes); the far field is
E -> -eps sigma^6 / (9 r^3). :func:`ees_energy_force_torque` evaluates it without the
cancellation of the closed form (see there).
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "aligned",
    "angular_velocity",
    "from_axis_angle",
    "inertia",
    "multiply",
    "normalize",
    "random_quaternions",
    "richardson",
    "richardson_step",
    "rotation_matrix",
    "rotation_rows",
    "rotational_energy",
    "rotational_energy_of",
    "select",
    "to_body",
    "to_space",
]

INERTIA = 0.2  # moment of inertia prefactor of a uniform solid ellipsoid, I = (m/5)(b^2 + c^2), ...


# --------------------------------------------------------------------------------------------
# plain arithmetic on components: floats or arrays alike (the NumPy path passes arrays, the
# compiled path of engine/asphere_compiled.py compiles these very functions for floats). A
# rotation matrix is the 9-tuple of its entries row by row (a00, a01, a02, a10, ..., a22).


def select(cond, a, b):
    """np.where(cond, a, b); the compiled path gives scalars `a if cond else b`."""
    return np.where(cond, a, b)


def rotation_rows(w, i, j, k):
    """The entries of A(q) row by row (see :func:`rotation_matrix`), q = (w, i, j, k) unit."""
    w2, i2, j2, k2 = w * w, i * i, j * j, k * k
    ij, ik, jk = 2.0 * i * j, 2.0 * i * k, 2.0 * j * k
    wi, wj, wk = 2.0 * w * i, 2.0 * w * j, 2.0 * w * k
    return (w2 + i2 - j2 - k2, ij - wk, ik + wj,
            ij + wk, w2 - i2 + j2 - k2, jk - wi,
            ik - wj, jk + wi, w2 - i2 - j2 + k2)


def to_body(a, v0, v1, v2):
    """A^T v: a space-frame vector in the body frame (a: the 9 entries of A), summed in index order."""
    return (a[0] * v0 + a[3] * v1 + a[6] * v2,
            a[1] * v0 + a[4] * v1 + a[7] * v2,
            a[2] * v0 + a[5] * v1 + a[8] * v2)


def to_space(a, v0, v1, v2):
    """A v: a body-frame vector in the space frame (a: the 9 entries of A), summed in index order."""
    return (a[0] * v0 + a[1] * v1 + a[2] * v2,
            a[3] * v0 + a[4] * v1 + a[5] * v2,
            a[6] * v0 + a[7] * v1 + a[8] * v2)


def body_omega(a, l0, l1, l2, m0, m1, m2):
    """Body-frame angular velocity diag(1/I) A^T L [1/time], 0 where a moment I is 0."""
    b0, b1, b2 = to_body(a, l0, l1, l2)
    return (select(m0 != 0.0, b0 / select(m0 != 0.0, m0, 1.0), 0.0),
            select(m1 != 0.0, b1 / select(m1 != 0.0, m1, 1.0), 0.0),
            select(m2 != 0.0, b2 / select(m2 != 0.0, m2, 1.0), 0.0))


def omega_quat(o0, o1, o2, w, i, j, k):
    """(0, ω) ⊗ q, the pure-vector Hamilton product of §11.2."""
    return (-o0 * i - o1 * j - o2 * k,
            w * o0 + o1 * k - o2 * j,
            w * o1 + o2 * i - o0 * k,
            w * o2 + o0 * j - o1 * i)


def normalized(w, i, j, k):
    """q / |q| as q * (1/sqrt(w^2+i^2+j^2+k^2))."""
    inv = 1.0 / np.sqrt(w * w + i * i + j * j + k * k)
    return w * inv, i * inv, j * inv, k * inv


def _omega_of(w, i, j, k, l0, l1, l2, m0, m1, m2):
    """(0, ω) ⊗ q with ω = A diag(1/I) A^T L the space-frame angular velocity."""
    a = rotation_rows(w, i, j, k)
    b0, b1, b2 = body_omega(a, l0, l1, l2, m0, m1, m2)
    o0, o1, o2 = to_space(a, b0, b1, b2)
    return omega_quat(o0, o1, o2, w, i, j, k)


def richardson_step(w, i, j, k, l0, l1, l2, m0, m1, m2, dtq):
    """One Richardson step of q = (w, i, j, k) over dt = 2 dtq (see :func:`richardson`), on
    components: returns the new (w, i, j, k). L = (l0, l1, l2) space frame, I = (m0, m1, m2)."""
    half = 0.5 * dtq
    q0, q1, q2, q3 = _omega_of(w, i, j, k, l0, l1, l2, m0, m1, m2)
    f0, f1, f2, f3 = normalized(w + dtq * q0, i + dtq * q1, j + dtq * q2, k + dtq * q3)
    h0, h1, h2, h3 = normalized(w + half * q0, i + half * q1, j + half * q2, k + half * q3)
    q0, q1, q2, q3 = _omega_of(h0, h1, h2, h3, l0, l1, l2, m0, m1, m2)
    h0, h1, h2, h3 = normalized(h0 + half * q0, h1 + half * q1, h2 + half * q2, h3 + half * q3)
    n0, n1, n2, n3 = normalized(2.0 * h0 - f0, 2.0 * h1 - f1, 2.0 * h2 - f2, 2.0 * h3 - f3)
    point = (m0 == 0.0) & (m1 == 0.0) & (m2 == 0.0)
    return select(point, w, n0), select(point, i, n1), select(point, j, n2), select(point, k, n3)


# --------------------------------------------------------------------------------------------
# quaternions (§11.3)


def normalize(q: np.ndarray) -> np.ndarray:
    """Unit quaternion q / |q|, (..., 4) -> (..., 4). Computed as q * (1/sqrt(w^2+i^2+j^2+k^2))."""
    q = np.asarray(q, dtype=np.float64)
    w, i, j, k = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    inv = 1.0 / np.sqrt(w * w + i * i + j * j + k * k)
    return q * inv[..., None]


def multiply(p: np.ndarray, q: np.ndarray) -> np.ndarray:
    """Hamilton product p ⊗ q of (..., 4) quaternions (rotation q first, then p)."""
    p = np.asarray(p, dtype=np.float64)
    q = np.asarray(q, dtype=np.float64)
    p0, p1, p2, p3 = p[..., 0], p[..., 1], p[..., 2], p[..., 3]
    q0, q1, q2, q3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return np.stack(
        [
            p0 * q0 - p1 * q1 - p2 * q2 - p3 * q3,
            p0 * q1 + p1 * q0 + p2 * q3 - p3 * q2,
            p0 * q2 - p1 * q3 + p2 * q0 + p3 * q1,
            p0 * q3 + p1 * q2 - p2 * q1 + p3 * q0,
        ],
        axis=-1,
    )


def rotation_matrix(q: np.ndarray) -> np.ndarray:
    """Rotation matrix A(q), (..., 4) -> (..., 3, 3), body -> space (§11.3); q must be unit.

    A = [[w²+i²-j²-k², 2(ij-wk),     2(ik+wj)    ],
         [2(ij+wk),     w²-i²+j²-k², 2(jk-wi)    ],
         [2(ik-wj),     2(jk+wi),     w²-i²-j²+k²]]
    """
    q = np.asarray(q, dtype=np.float64)
    rows = rotation_rows(q[..., 0], q[..., 1], q[..., 2], q[..., 3])
    a = np.empty(q.shape[:-1] + (3, 3))  # filled in place: no stacked copies (the ees profile's 30%)
    for n, entry in enumerate(rows):
        a[..., n // 3, n % 3] = entry
    return a


def entries(a: np.ndarray) -> tuple:
    """The 9-tuple of a (..., 3, 3) matrix's entries row by row (views)."""
    return tuple(a[..., n // 3, n % 3] for n in range(9))


def from_axis_angle(axis: np.ndarray, angle: np.ndarray, *, degrees: bool = False,
                    normalize_axis: bool = True) -> np.ndarray:
    """Unit quaternion of a rotation by ``angle`` about ``axis`` (..., 3) -> (..., 4).

    q = (cos(θ/2), sin(θ/2) â). With ``normalize_axis=False`` the axis is used as given and the
    whole quaternion is normalised afterwards: LAMMPS's ``set ... quat a b c θ`` (note after
    §11.3), so ``(1, 1, 0), 50°`` is then a 66.8° rotation.
    """
    axis = np.asarray(axis, dtype=np.float64)
    theta = np.asarray(angle, dtype=np.float64)
    if degrees:
        theta = np.deg2rad(theta)
    if normalize_axis:
        axis = axis / np.linalg.norm(axis, axis=-1, keepdims=True)
    half = 0.5 * theta
    axis, half = np.broadcast_arrays(axis, half[..., None])
    q = np.concatenate([np.cos(half[..., :1]), np.sin(half) * axis], axis=-1)
    return normalize(q)


def random_quaternions(rng: np.random.Generator, shape: int | tuple[int, ...]) -> np.ndarray:
    """Unit quaternions (*shape, 4) uniformly distributed on SO(3) (normalised 4-d Gaussians)."""
    shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
    return normalize(rng.standard_normal(shape + (4,)))


def aligned(shape: int | tuple[int, ...] = ()) -> np.ndarray:
    """Identity quaternions (1, 0, 0, 0) of shape (*shape, 4): body axes along x, y, z."""
    shape = (shape,) if isinstance(shape, (int, np.integer)) else tuple(shape)
    q = np.zeros(shape + (4,))
    q[..., 0] = 1.0
    return q


# --------------------------------------------------------------------------------------------
# rigid-body rotation (§11.2)


def inertia(mass: np.ndarray, shape: np.ndarray) -> np.ndarray:
    """Principal moments of a uniform solid ellipsoid [mass*length^2], (...,) and (..., 3) -> (..., 3).

    I = (m/5) (b² + c², a² + c², a² + b²) for semi-axes (a, b, c).
    """
    m = INERTIA * np.asarray(mass, dtype=np.float64)[..., None]
    s = np.asarray(shape, dtype=np.float64)
    a2, b2, c2 = s[..., 0] * s[..., 0], s[..., 1] * s[..., 1], s[..., 2] * s[..., 2]
    return m * np.stack([b2 + c2, a2 + c2, a2 + b2], axis=-1)


def _stack(parts: tuple, shape: tuple) -> np.ndarray:
    """Components -> one (*shape, len(parts)) array, filled in place."""
    out = np.empty(shape + (len(parts),))
    for n, part in enumerate(parts):
        out[..., n] = part
    return out


def _components(v: np.ndarray, n: int) -> tuple:
    return tuple(v[..., c] for c in range(n))


def angular_velocity(q: np.ndarray, angmom: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """Space-frame angular velocity ω = A diag(1/I) A^T L [1/time], (..., 3); 0 where I = 0."""
    q = np.asarray(q, dtype=np.float64)
    angmom = np.asarray(angmom, dtype=np.float64)
    moments = np.asarray(inertia, dtype=np.float64)
    a = rotation_rows(*_components(q, 4))
    omega = to_space(a, *body_omega(a, *_components(angmom, 3), *_components(moments, 3)))
    shape = np.broadcast_shapes(q.shape[:-1], angmom.shape[:-1], moments.shape[:-1])
    return _stack(omega, shape)


def richardson(q: np.ndarray, angmom: np.ndarray, inertia: np.ndarray, dtq) -> np.ndarray:
    """One Richardson step of dq/dt = ½ (0,ω) ⊗ q over dt = 2 dtq (§11.2, fix nve/asphere).

    q (..., 4) unit, angmom L (..., 3) space frame, inertia (..., 3) principal moments; ``dtq``
    (= dt/2) a float or an array broadcastable against ``q.shape[:-1]`` (e.g. ``dtq[:, None]`` for
    per-case values with (C, N, 4) quaternions). Same order of operations as LAMMPS
    (:func:`richardson_step` on the components):

        ω = ω(q, L);  wq = (0,ω) ⊗ q
        q_full = normalize(q + dtq wq);  q_half = normalize(q + ½ dtq wq)
        ω' = ω(q_half, L);  q_half = normalize(q_half + ½ dtq (0,ω') ⊗ q_half)
        q_new = normalize(2 q_half - q_full)

    Atoms whose three moments are all 0 (point particles) keep q unchanged, bit for bit.
    """
    q = np.asarray(q, dtype=np.float64)
    angmom = np.asarray(angmom, dtype=np.float64)
    moments = np.asarray(inertia, dtype=np.float64)
    dtq = np.asarray(dtq, dtype=np.float64)
    new = richardson_step(*_components(q, 4), *_components(angmom, 3), *_components(moments, 3), dtq)
    shape = np.broadcast_shapes(q.shape[:-1], angmom.shape[:-1], moments.shape[:-1], dtq.shape)
    return _stack(new, shape)


def rotational_energy(q: np.ndarray, angmom: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """Rotational kinetic energy ½ L·ω = ½ Σ_k I_k ω_body,k² [mass*velocity^2], (...).

    Multiply by mvv2e for energy units (compute erotate/asphere). Components with I = 0 count 0.
    """
    q = np.asarray(q, dtype=np.float64)
    moments = np.asarray(inertia, dtype=np.float64)
    return rotational_energy_of(*_components(q, 4), *_components(np.asarray(angmom, dtype=np.float64), 3),
                                *_components(moments, 3))


def rotational_energy_of(w, i, j, k, l0, l1, l2, m0, m1, m2):
    """½ Σ_k I_k ω_body,k² of quaternion (w, i, j, k), angular momentum L and moments I given by
    components (floats or arrays) [mass*velocity^2]: :func:`rotational_energy`'s arithmetic, which
    the compiled ellipsoid kernel (engine/asphere_compiled.py) compiles as it is."""
    wb = body_omega(rotation_rows(w, i, j, k), l0, l1, l2, m0, m1, m2)
    return 0.5 * (m0 * wb[0] * wb[0] + m1 * wb[1] * wb[1] + m2 * wb[2] * wb[2])
