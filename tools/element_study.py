"""Which locking-free tetrahedron: the measurement behind the choice (issue 11).

    python tools/element_study.py [--quick] [--out docs/accuracy/element_choice]

The clamped cantilever of ``scenes/validation/cantilever.py`` under a small tip load, solved
in small-strain linear elasticity (the corotational models' tangent at rest) with three
tetrahedra on gmsh meshes of several sizes, at Poisson ratios 0.3, 0.45 and 0.49:

- ``linear``: the 4-node tetrahedron (today's element);
- ``nodal_pressure``: the 4-node tetrahedron with its volumetric strain averaged over each
  node's elements (Bonet and Burton's average nodal pressure; the deviatoric part stays per
  element). No new unknowns; the stiffness couples a node to its neighbours' neighbours;
- ``quadratic``: the 10-node tetrahedron (a node at each edge's midpoint), four-point rule.

Each is assembled here with NumPy and solved by CHOLMOD, so the table is the element's
accuracy per degree of freedom and per stiffness entry (a proxy for the cost of a product or a
factorization), not a step time of the simulator. The tip deflection (the end face's
area-weighted mean) is compared with Timoshenko's. Writes element_choice.csv and .md.
"""

from __future__ import annotations

import argparse
import csv
import time
from pathlib import Path

import numpy as np
import scipy.sparse as sp

import warpsoft as ws
from warpsoft.io.runner import load_scene_module

ROOT = Path(__file__).resolve().parents[1]
LENGTH, WIDTH, HEIGHT, E, LOAD = 0.1, 0.01, 0.01, 1e6, 0.01  # m, m, m, Pa, N (the validation scene's)
EDGES = np.array([[0, 1], [0, 2], [0, 3], [1, 2], [1, 3], [2, 3]])  # a 10-node element's nodes 4-9
QUAD_A, QUAD_B = 0.5854101966249685, 0.1381966011250105  # the four-point rule's barycentric coordinates


def corner_gradients(nodes: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Gradients of the barycentric coordinates ``(m, 4, 3)`` (1/m) and volumes ``(m,)`` (m^3)."""
    x = nodes[tets[:, :4]]
    dm = np.stack([x[:, 1] - x[:, 0], x[:, 2] - x[:, 0], x[:, 3] - x[:, 0]], axis=2)
    inv = np.linalg.inv(dm)  # row k: the gradient of L_{k+1}
    g = np.concatenate([-inv.sum(axis=1, keepdims=True), inv], axis=1)
    return g, np.abs(np.linalg.det(dm)) / 6.0


def strain_matrix(grad: np.ndarray) -> np.ndarray:
    """``B`` (engineering shear, Voigt xx yy zz xy yz zx) from node gradients ``(m, k, 3)``:
    ``(m, 6, 3k)``."""
    m, k, _ = grad.shape
    b = np.zeros((m, 6, k, 3))
    gx, gy, gz = grad[..., 0], grad[..., 1], grad[..., 2]
    b[:, 0, :, 0], b[:, 1, :, 1], b[:, 2, :, 2] = gx, gy, gz
    b[:, 3, :, 0], b[:, 3, :, 1] = gy, gx
    b[:, 4, :, 1], b[:, 4, :, 2] = gz, gy
    b[:, 5, :, 0], b[:, 5, :, 2] = gz, gx
    return b.reshape(m, 6, 3 * k)


def elasticity(mu: float, lam: float) -> np.ndarray:
    """The isotropic 6x6 ``D`` (Pa) for Lame parameters ``mu``, ``lam``."""
    d = np.zeros((6, 6))
    d[:3, :3] = lam
    d[np.arange(3), np.arange(3)] += 2.0 * mu
    d[np.arange(3, 6), np.arange(3, 6)] = mu
    return d


def scatter(elems: np.ndarray, ke: np.ndarray, n: int) -> sp.csc_matrix:
    """Sum the element matrices ``(m, 3k, 3k)`` over their nodes ``(m, k)`` into ``(3n, 3n)``."""
    dof = (3 * elems[:, :, None] + np.arange(3)).reshape(len(elems), -1)
    rows = np.broadcast_to(dof[:, :, None], ke.shape).ravel()
    cols = np.broadcast_to(dof[:, None, :], ke.shape).ravel()
    return sp.csc_matrix((ke.ravel(), (rows, cols)), shape=(3 * n, 3 * n))


def linear_stiffness(nodes, tets, mu, lam, nodal_pressure=False) -> sp.csc_matrix:
    """4-node tetrahedra; with ``nodal_pressure`` the volumetric part from nodal averages."""
    g, vol = corner_gradients(nodes, tets)
    b = strain_matrix(g)
    if not nodal_pressure:
        return scatter(tets, vol[:, None, None] * b.transpose(0, 2, 1) @ elasticity(mu, lam) @ b, len(nodes))
    kappa = lam + 2.0 * mu / 3.0
    k_dev = scatter(tets, vol[:, None, None] * b.transpose(0, 2, 1) @ elasticity(mu, -2.0 * mu / 3.0) @ b, len(nodes))
    # theta_a = sum_e (V_e / 4) div_e u / V_a: one row per node a over the DOFs of its elements
    share = np.repeat(vol / 4.0, 4)
    v_node = np.bincount(tets.ravel(), share, minlength=len(nodes))
    rows = np.repeat(tets.ravel(), 12)
    dof = (3 * tets[:, :, None] + np.arange(3)).reshape(len(tets), 12)
    cols = np.repeat(dof, 4, axis=0).ravel()
    vals = (np.repeat(g.reshape(len(tets), 12), 4, axis=0) * (share / v_node[tets.ravel()])[:, None]).ravel()
    avg = sp.csr_matrix((vals, (rows, cols)), shape=(len(nodes), 3 * len(nodes)))
    return (k_dev + avg.T @ sp.diags(kappa * v_node) @ avg).tocsc()


def quadratic_mesh(nodes: np.ndarray, tets: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """A node at each edge's midpoint: the nodes and the 10-node elements ``(m, 10)``."""
    pairs = np.sort(tets[:, EDGES].reshape(-1, 2), axis=1)
    edges, which = np.unique(pairs, axis=0, return_inverse=True)
    mids = 0.5 * (nodes[edges[:, 0]] + nodes[edges[:, 1]])
    elems = np.concatenate([tets, len(nodes) + which.reshape(len(tets), 6)], axis=1)
    return np.concatenate([nodes, mids]), elems


def quadratic_stiffness(nodes, elems, mu, lam) -> sp.csc_matrix:
    """10-node tetrahedra with straight edges, the four-point rule (exact for their ``B^T D B``)."""
    g, vol = corner_gradients(nodes, elems)
    d = elasticity(mu, lam)
    ke = 0.0
    for q in range(4):
        bary = np.full(4, QUAD_B)
        bary[q] = QUAD_A
        grad = np.concatenate([(4.0 * bary[:, None] - 1.0) * g,  # corners: (4 L_i - 1) grad L_i
                               4.0 * (bary[EDGES[:, 0], None] * g[:, EDGES[:, 1]]
                                      + bary[EDGES[:, 1], None] * g[:, EDGES[:, 0]])], axis=1)
        b = strain_matrix(grad)
        ke = ke + (vol / 4.0)[:, None, None] * b.transpose(0, 2, 1) @ d @ b
    return scatter(elems, ke, len(nodes))


def end_face_weights(mesh: ws.TetMesh, nodes: np.ndarray, quadratic: bool) -> np.ndarray:
    """Each node's share of the end face x = LENGTH by area (sums to 1). On the quadratic mesh
    (``nodes``: the corners, then the midpoints in :func:`quadratic_mesh`'s order) each face is
    split at its edges' midpoints into four triangles."""
    tris = mesh.surface()
    tris = tris[np.all(np.abs(mesh.nodes[tris][..., 0] - LENGTH) < 1e-9, axis=1)]
    if quadratic:
        edges = np.unique(np.sort(mesh.tets[:, EDGES].reshape(-1, 2), axis=1), axis=0)
        mid = {(int(a), int(b)): mesh.num_nodes + i for i, (a, b) in enumerate(edges)}
        ab, bc, ca = ([mid[tuple(sorted((int(u), int(v))))] for u, v in zip(tris[:, i], tris[:, j], strict=True)]
                      for i, j in ((0, 1), (1, 2), (2, 0)))
        a, b, c = tris.T
        tris = np.concatenate([np.stack(t, axis=1) for t in ((a, ab, ca), (ab, b, bc), (ca, bc, c), (ab, bc, ca))])
    x = nodes[tris]
    area = 0.5 * np.linalg.norm(np.cross(x[:, 1] - x[:, 0], x[:, 2] - x[:, 0]), axis=1)
    w = np.zeros(len(nodes))
    np.add.at(w, tris.ravel(), np.repeat(area / 3.0, 3))
    return w / w.sum()


def solve_tip(element: str, mesh: ws.TetMesh, nu: float) -> dict:
    """Tip deflection (m, positive down) and the system's size for one element and mesh."""
    from cvxopt import cholmod, matrix, spmatrix

    mu, lam = E / (2 * (1 + nu)), E * nu / ((1 + nu) * (1 - 2 * nu))
    t0 = time.perf_counter()
    if element == "quadratic":
        nodes, elems = quadratic_mesh(mesh.nodes, mesh.tets)
        k = quadratic_stiffness(nodes, elems, mu, lam)
    else:
        nodes, elems = mesh.nodes, mesh.tets
        k = linear_stiffness(nodes, elems, mu, lam, nodal_pressure=element == "nodal_pressure")
    weights = end_face_weights(mesh, nodes, element == "quadratic")
    free = np.flatnonzero(np.repeat(nodes[:, 0] > 1e-9, 3))
    f = np.zeros(3 * len(nodes))
    f[2::3] = -LOAD * weights
    kf = k[free][:, free].tocoo()
    assembled = time.perf_counter() - t0
    t0 = time.perf_counter()
    rhs = matrix(f[free])
    cholmod.linsolve(spmatrix(kf.data, kf.row.astype(int), kf.col.astype(int), kf.shape), rhs)
    solved = time.perf_counter() - t0
    u = np.zeros(3 * len(nodes))
    u[free] = np.array(rhs).ravel()
    return {"dofs": len(free), "nonzeros": kf.nnz, "deflection": -float(weights @ u[2::3]),
            "assembly_s": assembled, "solve_s": solved}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--quick", action="store_true", help="two mesh sizes per element, for a check")
    ap.add_argument("--out", default="out/element_choice")
    args = ap.parse_args(argv)
    cantilever = load_scene_module(ROOT / "scenes/validation/cantilever.py")
    fine = [10 / 4, 10 / 6, 10 / 8, 10 / 10]  # mm
    sizes = {"linear": fine, "nodal_pressure": fine, "quadratic": [10 / 1, 10 / 2, 10 / 3, 10 / 4, 10 / 6]}
    if args.quick:
        sizes = {k: v[1:3] for k, v in sizes.items()}
    rows = []
    for element, hs in sizes.items():
        for h in hs:
            shape = ws.shapes.Box((0.0, -WIDTH / 2, -HEIGHT / 2), (LENGTH, WIDTH, HEIGHT))
            mesh = ws.mesh_shape(shape, h * 1e-3, name="beam")
            for nu in (0.3, 0.45, 0.49):
                r = solve_tip(element, mesh, nu)
                exact = cantilever.timoshenko_tip_deflection(poisson_ratio=nu, young_modulus=E, tip_force=LOAD)
                rows.append({"element": element, "mesh_mm": round(h, 3), "nu": nu, **r,
                             "error": r["deflection"] / exact - 1.0})
                print(f"{element:15s} h {h:5.2f} mm nu {nu:4.2f}: {r['dofs']:7d} DOFs {r['nonzeros']:9d} entries  "
                      f"error {100 * rows[-1]['error']:+7.2f} %  (solve {r['solve_s']:.2f} s)", flush=True)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    with open(out / "element_choice.csv", "w", newline="") as fh:
        writer = csv.DictWriter(fh, fieldnames=list(rows[0]))
        writer.writeheader()
        writer.writerows(rows)
    lines = ["| element | mesh (mm) | DOFs | stiffness entries | error nu 0.3 | nu 0.45 | nu 0.49 |",
             "|---|---|---|---|---|---|---|"]
    for i in range(0, len(rows), 3):
        a, b, c = rows[i:i + 3]
        lines.append(f"| {a['element']} | {a['mesh_mm']} | {a['dofs']} | {a['nonzeros']} | {100 * a['error']:+.2f} % "
                     f"| {100 * b['error']:+.2f} % | {100 * c['error']:+.2f} % |")
    (out / "element_choice.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
