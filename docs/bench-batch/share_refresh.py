# Four quasi-static bent beams (moduli 2, 3, 5, 7 x 1e5 Pa) as worlds, pcg with the blocks preconditioner on the CPU
# device: one block shared (share_tolerance 1e-10: exact multiples at rest) against one block per world (0.0).
# Printed: blocks, refreshes, per step (CG iterations, Newton iterations), the lowest node z of each world (m).
import numpy as np, time
import warpsoft as ws
def beam(E):
    scene = ws.Scene("b", gravity=(0, 0, -9.81), dt=1.0, static=True, steps=8)
    body = scene.add_body("beam", ws.box_grid((0, 0, 0), (0.1, 0.01, 0.01), (20, 2, 2)), ws.Material(E, 0.45, 1000.0))
    scene.fix(body, ws.OnPlane((0, 0, 0), (1, 0, 0)))
    scene.add_force(body, ws.OnPlane((0.1, 0, 0), (1, 0, 0)), lambda t: (0, 0, -0.05 * min(t, 6)))
    return scene
for tol in (1e-10, 0.0):
    sim = ws.Simulator(ws.finalize([beam(E) for E in (2e5, 3e5, 5e5, 7e5)], "cpu"), device="cpu", solver="pcg", preconditioner="blocks", share_tolerance=tol)
    its = []
    for k in range(8):
        st = sim.step(); its.append((st.cg_iterations, st.newton_iterations))
    print(tol, "blocks", sim.solver.precond.blocks, "refreshes", sim.solver.precond.refreshes, its, "tip z", [round(float(sim.positions(w)[:, 2].min()), 4) for w in range(4)])
