"""Generic constraint-row kernels. Every row's ``H = d delta / dq`` is stored as sparse
entries ``(h_row[k], h_node[k], h_coef[k])``: row id, node id, 3-vector coefficient."""

import warp as wp

from .. import OPTIONS

wp.set_module_options(OPTIONS)


@wp.func
def write_point_entries(
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    first: int,
    row: int,
    nodes: wp.vec4i,
    weights: wp.vec4d,
    direction: wp.vec3d,
):
    """The four entries ``first .. first+3`` of row ``row`` for a point mapped into a
    tetrahedron: ``H`` at node ``nodes[a]`` is ``weights[a] * direction``."""
    for a in range(4):
        h_row[first + a] = row
        h_node[first + a] = nodes[a]
        h_coef[first + a] = weights[a] * direction


@wp.kernel
def rows_to_columns(
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    column_of_row: wp.array(dtype=wp.int32),
    columns: wp.array2d(dtype=wp.vec3d),
):
    """``columns[c] += H^T e_row`` for the rows that own a column (``column_of_row >= 0``)."""
    k = wp.tid()
    c = column_of_row[h_row[k]]
    if c >= 0:
        wp.atomic_add(columns, c, h_node[k], h_coef[k])


@wp.kernel
def rows_times_columns(
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    x: wp.array2d(dtype=wp.vec3d),
    scale: wp.float64,
    columns: wp.array(dtype=wp.int32),
    w: wp.array2d(dtype=wp.float64),
):
    """``w[row, c] += scale * H[row] . x[c]`` (launched over entries x columns) for the columns
    ``c < columns[0]`` in use: ``W = s H X``. An inert entry (0: an unused contact slot's) adds
    nothing and is skipped."""
    k, c = wp.tid()
    if c >= columns[0]:
        return
    coef = h_coef[k]
    if coef[0] != wp.float64(0.0) or coef[1] != wp.float64(0.0) or coef[2] != wp.float64(0.0):
        wp.atomic_add(w, h_row[k], c, scale * wp.dot(coef, x[c, h_node[k]]))


@wp.kernel
def rows_times_vector(
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    x: wp.array2d(dtype=wp.vec3d),
    column: int,
    out: wp.array(dtype=wp.float64),
):
    """``out[row] += H[row] . x[column]`` (launched over entries): ``delta_free = delta + H dx_free``."""
    k = wp.tid()
    wp.atomic_add(out, h_row[k], wp.dot(h_coef[k], x[column, h_node[k]]))


@wp.kernel
def correct_with_columns(
    dx_free: wp.array(dtype=wp.vec3d),
    x: wp.array2d(dtype=wp.vec3d),
    lam: wp.array(dtype=wp.float64),
    node_world: wp.array(dtype=wp.int32),
    world_row_start: wp.array(dtype=wp.int32),
    world_actuators: wp.array(dtype=wp.int32),
    scale: wp.float64,
    dx: wp.array(dtype=wp.vec3d),
):
    """``dx = dx_free + scale sum_j lam_j x[j]`` over the actuator rows ``j`` of the node's world
    (``lam`` per row): the correction, with no further solve."""
    i = wp.tid()
    w = node_world[i]
    s = world_row_start[w]
    d = dx_free[i]
    for j in range(world_actuators[w]):
        d = d + (scale * lam[s + j]) * x[j, i]
    dx[i] = d


@wp.kernel
def force_rows_transpose_times(
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    lam: wp.array(dtype=wp.float64),
    scale: wp.float64,
    column_of_row: wp.array(dtype=wp.int32),
    node_world: wp.array(dtype=wp.int32),
    world_force_rows: wp.array(dtype=wp.int32),
    force: wp.array(dtype=wp.vec3d),
):
    """``force += scale H_f^T lam`` (launched over entries) over the force rows in use: a row
    whose column is below its world's count (the world of the entry's node)."""
    k = wp.tid()
    c = column_of_row[h_row[k]]
    if c >= 0 and c < world_force_rows[node_world[h_node[k]]]:
        wp.atomic_add(force, h_node[k], (scale * lam[h_row[k]]) * h_coef[k])


@wp.kernel
def rows_transpose_times(
    h_row: wp.array(dtype=wp.int32),
    h_node: wp.array(dtype=wp.int32),
    h_coef: wp.array(dtype=wp.vec3d),
    lam: wp.array(dtype=wp.float64),
    force: wp.array(dtype=wp.vec3d),
):
    """``force += H^T lam`` (N): the rows' forces on the nodes."""
    k = wp.tid()
    wp.atomic_add(force, h_node[k], lam[h_row[k]] * h_coef[k])


@wp.kernel
def add_motion(a: wp.array(dtype=wp.vec3d), b: wp.array(dtype=wp.vec3d), out: wp.array(dtype=wp.vec3d)):
    """``out = a + b`` (m): the free correction plus the rows' (solved from their forces)."""
    i = wp.tid()
    out[i] = a[i] + b[i]


@wp.kernel
def most_force_rows(world_force_rows: wp.array(dtype=wp.int32), columns: wp.array(dtype=wp.int32)):
    """One thread: ``columns[0]`` = the most force rows in use of any world (the compliance
    columns in use)."""
    most = wp.int32(0)
    for w in range(world_force_rows.shape[0]):
        most = wp.max(most, world_force_rows[w])
    columns[0] = most
