"""Four quasi-static bent beams (moduli 2, 3, 5, 7 x 1e5 Pa) as the worlds of one model, pcg
with the blocks preconditioner on the CPU device: one block shared (share_tolerance 1e-10, exact
multiples at rest) against one block per world (0.0). Printed: the blocks, the refreshes, per
step (CG iterations, Newton iterations), and the lowest node z of each world (m)."""

import warpsoft as ws


def beam(young_modulus: float) -> ws.Scene:
    scene = ws.Scene("b", gravity=(0, 0, -9.81), dt=1.0, static=True, steps=8)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)),
                          ws.Material(young_modulus, 0.45, 1000.0))
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), lambda t: (0, 0, -0.05 * min(t, 6)))
    return scene


for tol in (1e-10, 0.0):
    model = ws.finalize([beam(e) for e in (2e5, 3e5, 5e5, 7e5)], "cpu")
    sim = ws.Simulator(model, device="cpu", solver="pcg", preconditioner="blocks", share_tolerance=tol)
    its = []
    for _ in range(8):
        st = sim.step()
        its.append((st.cg_iterations, st.newton_iterations))
    low = [round(float(sim.positions(w)[:, 2].min()), 4) for w in range(4)]
    print(tol, "blocks", sim.solver.precond.blocks, "refreshes", sim.solver.precond.refreshes, its, "tip z", low)
