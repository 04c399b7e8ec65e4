"""The plate through its thickness, in layers: elastic-plastic return mapping per layer, moments and tangent.

Bending only (no membrane strain): a layer at height ``z`` above the mid-surface has the
strain ``e = z kappa`` with the curvature vector ``kappa = -(w_uu, w_vv, 2 w_uv)`` (1/mm).
Its plane-stress state follows :mod:`mppf.sim.plate.material` (Hill 48, isotropic
hardening) by the closest-point return mapping with associated flow
``d e_p = d gamma P s`` and ``d alpha = d gamma sqrt(s^T P s)``.

The return mapping is solved in the basis ``Q`` that diagonalises ``C^-1`` and ``P``
together (``Q^T C^-1 Q = I``, ``Q^T P Q = diag(lam)``): with ``tau = Q^T (e - e_p_old)``,

    s(dg) = Q diag(1 / (1 + dg lam)) tau,   s^T P s = sum_k lam_k tau_k^2 / (1 + dg lam_k)^2,

so the consistency condition ``sqrt(s^T P s) = sy(alpha_old + dg sqrt(s^T P s))`` is one
scalar Newton iteration per layer point (vectorised over cells x layers). The consistent
tangent is ``C_ep = X - (X n)(X n)^T / (n^T X n + h sbar^2 / (1 - h dg))`` with
``X = (C^-1 + dg P)^-1``, ``n = P s``, ``h`` the hardening slope.

Through the thickness: Gauss-Legendre points on the upper half (``z = xi t / 2``,
``0 < xi < 1``); the lower half is the mirror image (bending keeps the state odd in z,
and the yield function is even), so

    M = (t^2 / 2) sum_l w_l xi_l s_l,   D_T = (t^3 / 4) sum_l w_l xi_l^2 C_ep,l

(``M = (M_uu, M_vv, M_uv)`` in N mm / mm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.linalg

from mppf.sim.plate.material import PlateSteel

LAYERS = 8
"""Default Gauss points through the upper half thickness (16 through the whole)."""

RETURN_ITERATIONS = 30
"""Most Newton iterations of the scalar return mapping."""

RETURN_TOLERANCE = 1e-9
"""Relative tolerance of the consistency condition."""


@dataclass(frozen=True, eq=False)
class LayerState:
    """Plastic state of every layer point.

    Attributes
    ----------
    plastic_strain : (n, layers, 3) float
        e_p = (e_uu, e_vv, g_uv) of the upper-half layers.
    alpha : (n, layers) float
        Equivalent plastic strain.
    """

    plastic_strain: np.ndarray
    alpha: np.ndarray

    @classmethod
    def virgin(cls, n: int, layers: int = LAYERS) -> LayerState:
        """The state of ``n`` cells of a plate that never yielded."""
        return cls(np.zeros((n, layers, 3)), np.zeros((n, layers)))


class LayerLaw:
    """The steel's layer law and the through-thickness rule.

    Parameters
    ----------
    steel : PlateSteel
    layers : int
        Gauss points through the half thickness.
    """

    def __init__(self, steel: PlateSteel, layers: int = LAYERS):
        self.steel = steel
        self.c = steel.elastic_matrix()
        self.c_inv = np.linalg.inv(self.c)
        self.p = steel.hill_matrix()
        self.lam, self.q = scipy.linalg.eigh(self.p, self.c_inv)
        xi, w = np.polynomial.legendre.leggauss(layers)
        self.xi = 0.5 * (xi + 1.0)
        self.w = 0.5 * w

    def stress(self, strain, plastic_strain, alpha, yield_factor, alpha_hint=None):
        """Return mapping of layer points.

        Parameters
        ----------
        strain : (n, L, 3) float
            Total strain of the layers.
        plastic_strain : (n, L, 3) float
            Committed plastic strain.
        alpha : (n, L) float
            Committed equivalent plastic strain.
        yield_factor : (n,) float
            Local factor on the initial yield stress.
        alpha_hint : (n, L) float, optional
            A guess of the new equivalent plastic strain (e.g. of the previous Newton
            iterate): the scalar Newton iteration starts from it.

        Returns
        -------
        stress : (n, L, 3) float, MPa
        scale : (n, L, 3) float
            The consistent tangent is ``Q diag(scale) Q^T - r r^T`` (MPa) ...
        rank_one : (n, L, 3) float
            ... with this ``r`` (0 where elastic: ``scale`` = 1 gives ``C = Q Q^T``).
        plastic_strain, alpha : (n, L, 3), (n, L) float
            The updated state.
        """
        shape = alpha.shape
        tau = (strain - plastic_strain).reshape(-1, 3) @ self.q
        lam = self.lam
        sbar = np.sqrt(np.maximum(lam[0] * tau[:, 0] ** 2 + lam[1] * tau[:, 1] ** 2 + lam[2] * tau[:, 2] ** 2, 0.0))
        factor = np.broadcast_to(np.asarray(yield_factor, dtype=float)[:, None], shape).ravel()
        flow, _ = self.steel.flow_stress_mpa(alpha.ravel(), factor)
        yielding = np.nonzero(sbar > flow * (1.0 + RETURN_TOLERANCE))[0]
        scale = np.ones_like(tau)
        rank_one = np.zeros_like(tau)
        new_alpha = alpha.ravel().copy()
        if len(yielding):
            start = np.zeros(len(yielding))
            if alpha_hint is not None:
                hint = alpha_hint.ravel()[yielding]
                step = np.maximum(hint - new_alpha[yielding], 0.0)
                start = step / self.steel.flow_stress_mpa(hint, factor[yielding])[0]
            ratio, r, a = self._return(tau[yielding], new_alpha[yielding], factor[yielding], start)
            tau[yielding] *= ratio
            scale[yielding] = ratio
            rank_one[yielding] = r
            new_alpha[yielding] = a
        stress = tau @ self.q.T
        new_ep = plastic_strain.reshape(-1, 3).copy()
        new_ep[yielding] = strain.reshape(-1, 3)[yielding] - stress[yielding] @ self.c_inv.T
        return (stress.reshape(strain.shape), scale.reshape(strain.shape), rank_one.reshape(strain.shape),
                new_ep.reshape(strain.shape), new_alpha.reshape(shape))

    def _return(self, tau, alpha, factor, start):
        """Closest-point projection of yielding points given by their trial ``tau`` (m, 3).

        ``start`` (m,) is the first guess of the plastic multiplier ``dg``. Returns the
        factors ``1 / (1 + dg lam)`` (m, 3) (the stress is ``Q (tau / (1 + dg lam))``), the
        tangent's rank-one vector (m, 3) and the new equivalent plastic strain (m,).
        """
        l0, l1, l2 = self.lam
        t0, t1, t2 = tau[:, 0], tau[:, 1], tau[:, 2]
        a0, a1, a2 = l0 * t0 * t0, l1 * t1 * t1, l2 * t2 * t2
        dg = start
        for _ in range(RETURN_ITERATIONS + 1):
            r0, r1, r2 = 1.0 / (1.0 + dg * l0), 1.0 / (1.0 + dg * l1), 1.0 / (1.0 + dg * l2)
            q0, q1, q2 = a0 * r0 * r0, a1 * r1 * r1, a2 * r2 * r2
            sbar = np.sqrt(q0 + q1 + q2)
            curl = l0 * q0 * r0 + l1 * q1 * r1 + l2 * q2 * r2  # = -sbar dsbar/ddg = n^T X n
            alpha_new = alpha + dg * sbar
            flow, slope = self.steel.flow_stress_mpa(alpha_new, factor)
            g = sbar - flow
            if np.max(np.abs(g) / flow) <= RETURN_TOLERANCE:
                break
            dsbar = -curl / sbar
            dg = np.maximum(dg - g / (dsbar - slope * (sbar + dg * dsbar)), 0.0)
        ratio = np.column_stack([r0, r1, r2])
        # X n = Q (lam tau / d^2), n^T X n = sum lam^2 tau^2 / d^3
        xn = (self.lam * tau * ratio * ratio) @ self.q.T
        denom = curl + slope * sbar * sbar / np.maximum(1.0 - slope * dg, 1e-6)
        return ratio, xn / np.sqrt(denom)[:, None], alpha_new


def layered_response(law: LayerLaw, kappa, state: LayerState, thickness_mm, yield_factor, hint=None):
    """Moments and tangent stiffness of cells bent to ``kappa`` from the committed ``state``.

    Parameters
    ----------
    law : LayerLaw
    kappa : (n, 3) float
        Curvature vectors -(w_uu, w_vv, 2 w_uv), 1/mm.
    state : LayerState
        Committed plastic state (n cells).
    thickness_mm : (n,) float
        Local thickness.
    yield_factor : (n,) float
        Local yield factor.
    hint : LayerState, optional
        A nearby trial state (the previous Newton iterate's): speeds up the return mapping.

    Returns
    -------
    moment : (n, 3) float
        (M_uu, M_vv, M_uv), N mm / mm.
    tangent : LayeredTangent
        d moment / d kappa (its ``matrix()``: (n, 3, 3), N mm).
    trial : LayerState
        The state at ``kappa`` (commit it once the step has converged).
    """
    t = np.asarray(thickness_mm, dtype=float)
    z = 0.5 * t[:, None] * law.xi[None, :]
    strain = z[:, :, None] * np.asarray(kappa, dtype=float)[:, None, :]
    stress, scale, rank_one, ep, alpha = law.stress(strain, state.plastic_strain, state.alpha, yield_factor,
                                                    None if hint is None else hint.alpha)
    moment = 0.5 * t[:, None] ** 2 * np.einsum("l,nli->ni", law.w * law.xi, stress)
    return moment, LayeredTangent(law, t, scale, rank_one), LayerState(ep, alpha)


class LayeredTangent:
    """The consistent through-thickness tangent d moment / d kappa, assembled when asked for.

    Parameters
    ----------
    law : LayerLaw
    thickness_mm : (n,) float
    scale, rank_one : (n, L, 3) float
        The layer tangents ``Q diag(scale) Q^T - r r^T`` (:meth:`LayerLaw.stress`).
    """

    def __init__(self, law: LayerLaw, thickness_mm, scale, rank_one):
        self.law, self.thickness_mm, self.scale, self.rank_one = law, thickness_mm, scale, rank_one

    def matrix(self) -> np.ndarray:
        """(n, 3, 3) float, N mm: ``(t^3 / 4) sum_l w_l xi_l^2 C_ep,l``."""
        law = self.law
        weight = law.w * law.xi**2
        diagonal = np.einsum("l,nli->ni", weight, self.scale)
        weighted = self.rank_one * weight[None, :, None]
        tangent = (diagonal[:, None, :] * law.q[None, :, :]) @ law.q.T
        tangent -= np.matmul(weighted.transpose(0, 2, 1), self.rank_one)
        return 0.25 * self.thickness_mm[:, None, None] ** 3 * tangent
