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
    "rotation_matrix",
    "rotational_energy",
]

INERTIA = 0.2  # moment of inertia prefactor of a uniform solid ellipsoid, I = (m/5)(b^2 + c^2), ...


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
    w, i, j, k = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    w2, i2, j2, k2 = w * w, i * i, j * j, k * k
    ij, ik, jk = 2.0 * i * j, 2.0 * i * k, 2.0 * j * k
    wi, wj, wk = 2.0 * w * i, 2.0 * w * j, 2.0 * w * k
    a = np.empty(q.shape[:-1] + (3, 3))  # filled in place: no stacked copies (the ees profile's 30%)
    a[..., 0, 0] = w2 + i2 - j2 - k2
    a[..., 0, 1] = ij - wk
    a[..., 0, 2] = ik + wj
    a[..., 1, 0] = ij + wk
    a[..., 1, 1] = w2 - i2 + j2 - k2
    a[..., 1, 2] = jk - wi
    a[..., 2, 0] = ik - wj
    a[..., 2, 1] = jk + wi
    a[..., 2, 2] = w2 - i2 - j2 + k2
    return a


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


def _to_body(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A^T v for (..., 3, 3) and (..., 3), summed in index order."""
    return a[..., 0, :] * v[..., 0, None] + a[..., 1, :] * v[..., 1, None] + a[..., 2, :] * v[..., 2, None]


def _to_space(a: np.ndarray, v: np.ndarray) -> np.ndarray:
    """A v for (..., 3, 3) and (..., 3), summed in index order."""
    return a[..., :, 0] * v[..., 0, None] + a[..., :, 1] * v[..., 1, None] + a[..., :, 2] * v[..., 2, None]


def _body_omega(a: np.ndarray, angmom: np.ndarray, moments: np.ndarray) -> np.ndarray:
    """Body-frame angular velocity diag(1/I) A^T L, with 0 where I = 0."""
    wbody = _to_body(a, angmom)
    nonzero = moments != 0.0
    return np.where(nonzero, wbody / np.where(nonzero, moments, 1.0), 0.0)


def angular_velocity(q: np.ndarray, angmom: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """Space-frame angular velocity ω = A diag(1/I) A^T L [1/time], (..., 3); 0 where I = 0."""
    a = rotation_matrix(q)
    return _to_space(a, _body_omega(a, np.asarray(angmom, dtype=np.float64), np.asarray(inertia)))


def _omega_quat(omega: np.ndarray, q: np.ndarray) -> np.ndarray:
    """(0, ω) ⊗ q, the pure-vector Hamilton product of §11.2."""
    a0, a1, a2 = omega[..., 0], omega[..., 1], omega[..., 2]
    b0, b1, b2, b3 = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    out = np.empty(np.broadcast_shapes(omega.shape[:-1], q.shape[:-1]) + (4,))  # filled in place
    out[..., 0] = -a0 * b1 - a1 * b2 - a2 * b3
    out[..., 1] = b0 * a0 + a1 * b3 - a2 * b2
    out[..., 2] = b0 * a1 + a2 * b1 - a0 * b3
    out[..., 3] = b0 * a2 + a0 * b2 - a1 * b1
    return out


def richardson(q: np.ndarray, angmom: np.ndarray, inertia: np.ndarray, dtq) -> np.ndarray:
    """One Richardson step of dq/dt = ½ (0,ω) ⊗ q over dt = 2 dtq (§11.2, fix nve/asphere).

    q (..., 4) unit, angmom L (..., 3) space frame, inertia (..., 3) principal moments; ``dtq``
    (= dt/2) a float or an array broadcastable against ``q.shape[:-1]`` (e.g. ``dtq[:, None]`` for
    per-case values with (C, N, 4) quaternions). Same order of operations as LAMMPS:

        ω = ω(q, L);  wq = (0,ω) ⊗ q
        q_full = normalize(q + dtq wq);  q_half = normalize(q + ½ dtq wq)
        ω' = ω(q_half, L);  q_half = normalize(q_half + ½ dtq (0,ω') ⊗ q_half)
        q_new = normalize(2 q_half - q_full)

    Atoms whose three moments are all 0 (point particles) keep q unchanged, bit for bit.
    """
    q = np.asarray(q, dtype=np.float64)
    angmom = np.asarray(angmom, dtype=np.float64)
    moments = np.asarray(inertia, dtype=np.float64)
    dtq = np.asarray(dtq, dtype=np.float64)[..., None]
    half = 0.5 * dtq
    wq = _omega_quat(angular_velocity(q, angmom, moments), q)
    q_full = normalize(q + dtq * wq)
    q_half = normalize(q + half * wq)
    wq = _omega_quat(angular_velocity(q_half, angmom, moments), q_half)
    q_half = normalize(q_half + half * wq)
    q_new = normalize(2.0 * q_half - q_full)
    point = np.all(moments == 0.0, axis=-1)[..., None]
    return np.where(point, q, q_new)


def rotational_energy(q: np.ndarray, angmom: np.ndarray, inertia: np.ndarray) -> np.ndarray:
    """Rotational kinetic energy ½ L·ω = ½ Σ_k I_k ω_body,k² [mass*velocity^2], (...).

    Multiply by mvv2e for energy units (compute erotate/asphere). Components with I = 0 count 0.
    """
    a = rotation_matrix(q)
    moments = np.asarray(inertia, dtype=np.float64)
    wb = _body_omega(a, np.asarray(angmom, dtype=np.float64), moments)
    iw2 = moments * wb * wb
    return 0.5 * (iw2[..., 0] + iw2[..., 1] + iw2[..., 2])


