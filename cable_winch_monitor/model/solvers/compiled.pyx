# cython: language_level=3, boundscheck=False, wraparound=False, cdivision=True, initializedcheck=False
"""The solvers' inner loops, compiled: the batched Newton on one taut set's KKT conditions and the search over
taut sets around it, and the fusion's rope terms (length residuals, balance and their Jacobians), weighing by
the prior, KKT systems and moves, row by row.

The live node solves one sample at a time, where numpy's cost per call, not the arithmetic,
is the time (a Newton step of one sample is some forty numpy calls on 3 x 3 arrays). Here each
row is worked out on its own, in C, so a row's answer is the same bits whichever rows are solved
with it: the node, which solves its samples as they come, and replay, which solves a window of
them at once, agree to the last bit.
"""
from libc.math cimport INFINITY, acos, cos, fabs, fmax, fmin, sin, sqrt

cdef enum:
    MAX_SIZE = 10  # 6 pose unknowns and at most 4 tensions
    KKT_SIZE = 16  # the fusion's Gauss-Newton systems: 10 state unknowns and the 6 balance multipliers
    JACOBI_SWEEPS = 60  # one-sided Jacobi sweeps at most (a 10 x 10 system takes some eight)


cdef inline int solve_in_place(double *a, int stride, double *b, int size, double tiny=0.0, int columns=1) noexcept nogil:
    """Gaussian elimination with partial pivoting of a (size x size) system, row i of a at a + i * stride, for
    `columns` right-hand sides (row i of them at b + i * columns); the solutions in b. Returns 0, or 1 where a
    pivot is no larger than `tiny` (zero: exactly zero, as LAPACK's gesv reports a singular system)."""
    cdef Py_ssize_t i, j, k, c, pivot
    cdef double largest, factor, swap
    for k in range(size):
        pivot = k
        largest = fabs(a[k * stride + k])
        for i in range(k + 1, size):
            if fabs(a[i * stride + k]) > largest:
                largest = fabs(a[i * stride + k])
                pivot = i
        if largest <= tiny:
            return 1
        if pivot != k:
            for j in range(size):
                swap = a[k * stride + j]
                a[k * stride + j] = a[pivot * stride + j]
                a[pivot * stride + j] = swap
            for c in range(columns):
                swap = b[k * columns + c]
                b[k * columns + c] = b[pivot * columns + c]
                b[pivot * columns + c] = swap
        for i in range(k + 1, size):
            factor = a[i * stride + k] / a[k * stride + k]
            if factor != 0.0:
                for j in range(k + 1, size):
                    a[i * stride + j] -= factor * a[k * stride + j]
                for c in range(columns):
                    b[i * columns + c] -= factor * b[k * columns + c]
    for k in range(size - 1, -1, -1):
        for c in range(columns):
            for j in range(k + 1, size):
                b[k * columns + c] -= a[k * stride + j] * b[j * columns + c]
            b[k * columns + c] /= a[k * stride + k]
    return 0


cdef int least_squares_in_place(double (*a)[MAX_SIZE], double *b, int size) noexcept nogil:
    """The least-squares solution of minimum norm of a (size x size) system in b, singular values below 1e-13
    of the largest taken as zero, as numpy.linalg.lstsq(a, b, rcond=1e-13) gives it, so that a redundant
    system (four taut ropes of equal lengths) still gives a step. The singular value decomposition is
    one-sided Jacobi's (Hestenes: plane rotations of a's columns until they are orthogonal), accurate to
    the last bits on a system this small. Returns 0, or 1 where a is not finite."""
    cdef double u[MAX_SIZE][MAX_SIZE]  # a's columns, rotated until orthogonal: U times the singular values
    cdef double v[MAX_SIZE][MAX_SIZE]  # the same rotations of the identity: V
    cdef double norms[MAX_SIZE]
    cdef double alpha, beta, gamma, zeta, t, c, sn, up, uq, largest = 0.0, projection
    cdef int sweep, p, q, i, rotated
    for i in range(size):
        for p in range(size):
            u[i][p] = a[i][p]
            v[i][p] = 1.0 if i == p else 0.0
    for sweep in range(JACOBI_SWEEPS):
        rotated = 0
        for p in range(size - 1):
            for q in range(p + 1, size):
                alpha = beta = gamma = 0.0
                for i in range(size):
                    alpha += u[i][p] * u[i][p]
                    beta += u[i][q] * u[i][q]
                    gamma += u[i][p] * u[i][q]
                if not fabs(gamma) > 1e-15 * sqrt(alpha * beta):  # orthogonal to rounding (or not finite)
                    continue
                rotated = 1
                zeta = (beta - alpha) / (2.0 * gamma)
                t = (1.0 if zeta >= 0.0 else -1.0) / (fabs(zeta) + sqrt(1.0 + zeta * zeta))
                c = 1.0 / sqrt(1.0 + t * t)
                sn = c * t
                for i in range(size):
                    up, uq = u[i][p], u[i][q]
                    u[i][p], u[i][q] = c * up - sn * uq, sn * up + c * uq
                    up, uq = v[i][p], v[i][q]
                    v[i][p], v[i][q] = c * up - sn * uq, sn * up + c * uq
        if not rotated:
            break
    for p in range(size):
        norms[p] = 0.0
        for i in range(size):
            norms[p] += u[i][p] * u[i][p]
        norms[p] = sqrt(norms[p])
        if not norms[p] < INFINITY:  # NaN or infinite: no solution
            return 1
        largest = fmax(largest, norms[p])
    cdef double solution[MAX_SIZE]
    for i in range(size):
        solution[i] = 0.0
    for p in range(size):
        if norms[p] <= 1e-13 * largest:  # zero too, where every column is
            continue
        projection = 0.0
        for i in range(size):
            projection += u[i][p] * b[i]
        projection /= norms[p] * norms[p]  # (u_p . b) / s_p, with u's column p = s_p u_p
        for i in range(size):
            solution[i] += projection * v[i][p]
    for i in range(size):
        b[i] = solution[i]
    return 0


cdef void rotate_left(double *rotation, double w0, double w1, double w2) noexcept nogil:
    """rotation <- exp([w]x) rotation for a row-major 3 x 3 rotation (Rodrigues; I + [w]x below an angle of
    1e-12, as geometry.rotations_from_vectors)."""
    cdef double angle = sqrt(w0 * w0 + w1 * w1 + w2 * w2)
    cdef double k[3][3]
    cdef double e[3][3]
    cdef double out[3][3]
    cdef double s, c
    cdef int i, j, m
    if angle < 1e-12:
        k[0][0] = 0.0; k[0][1] = -w2; k[0][2] = w1
        k[1][0] = w2; k[1][1] = 0.0; k[1][2] = -w0
        k[2][0] = -w1; k[2][1] = w0; k[2][2] = 0.0
        for i in range(3):
            for j in range(3):
                e[i][j] = k[i][j] + (1.0 if i == j else 0.0)
    else:
        k[0][0] = 0.0; k[0][1] = -w2 / angle; k[0][2] = w1 / angle
        k[1][0] = w2 / angle; k[1][1] = 0.0; k[1][2] = -w0 / angle
        k[2][0] = -w1 / angle; k[2][1] = w0 / angle; k[2][2] = 0.0
        s = sin(angle)
        c = 1.0 - cos(angle)
        for i in range(3):
            for j in range(3):
                e[i][j] = (1.0 if i == j else 0.0) + s * k[i][j] + c * (k[i][0] * k[0][j] + k[i][1] * k[1][j]
                                                                        + k[i][2] * k[2][j])
    for i in range(3):
        for j in range(3):
            out[i][j] = 0.0
            for m in range(3):
                out[i][j] += e[i][m] * rotation[3 * m + j]
    for i in range(3):
        for j in range(3):
            rotation[3 * i + j] = out[i][j]


cdef inline void cross3(const double *a, const double *b, double *out) noexcept nogil:
    out[0] = a[1] * b[2] - a[2] * b[1]
    out[1] = a[2] * b[0] - a[0] * b[2]
    out[2] = a[0] * b[1] - a[1] * b[0]


cdef inline void skew3(const double *v, double (*out)[3]) noexcept nogil:
    out[0][0] = 0.0; out[0][1] = -v[2]; out[0][2] = v[1]
    out[1][0] = v[2]; out[1][1] = 0.0; out[1][2] = -v[0]
    out[2][0] = -v[1]; out[2][1] = v[0]; out[2][2] = 0.0


cdef inline void rotate(const double *rotation, const double *vector, double *out) noexcept nogil:
    """out = R v for a row-major 3 x 3 R."""
    cdef int a
    for a in range(3):
        out[a] = rotation[3 * a] * vector[0] + rotation[3 * a + 1] * vector[1] + rotation[3 * a + 2] * vector[2]


cdef inline double cable_geometry(const double *rotation, const double *position, const double *attachment,
                                  const double *anchor, const double *rotated_cog, double *arm, double *lever,
                                  double *unit, double *moment) noexcept nogil:
    """A cable at a pose: its arm R b, lever arm about C, unit span from anchor to attachment and moment
    q x u about C; returns the span's length."""
    cdef int a
    cdef double norm
    rotate(rotation, attachment, arm)
    for a in range(3):
        lever[a] = arm[a] - rotated_cog[a]
        unit[a] = position[a] + arm[a] - anchor[a]
    norm = sqrt(unit[0] * unit[0] + unit[1] * unit[1] + unit[2] * unit[2])
    for a in range(3):
        unit[a] /= norm
    cross3(lever, unit, moment)
    return norm


cdef inline void pose_block(const double *arm, const double *lever, const double *unit, double norm, double weight,
                            double scale, double (*block)[6]) noexcept nogil:
    """The derivative of a cable's pull weight u and moment weight q x u (per `scale`) with respect to the pose
    (position, rotation vector on the left): weight (P, -P [r]x; [q]x P, [u]x [q]x - [q]x P [r]x), with
    P = (I - u u^T) / |s|."""
    cdef double p[3][3]
    cdef double sr[3][3]
    cdef double sq[3][3]
    cdef double su[3][3]
    cdef double pr[3][3]
    cdef double qp[3][3]
    cdef double value
    cdef int a, b, i
    for a in range(3):
        for b in range(3):
            p[a][b] = weight * ((1.0 if a == b else 0.0) - unit[a] * unit[b]) / norm
    skew3(arm, sr)
    skew3(lever, sq)
    skew3(unit, su)
    for a in range(3):
        for b in range(3):
            pr[a][b] = p[a][0] * sr[0][b] + p[a][1] * sr[1][b] + p[a][2] * sr[2][b]
            qp[a][b] = sq[a][0] * p[0][b] + sq[a][1] * p[1][b] + sq[a][2] * p[2][b]
    for a in range(3):
        for b in range(3):
            block[a][b] = p[a][b]
            block[a][3 + b] = -pr[a][b]
            block[3 + a][b] = qp[a][b] / scale
            value = 0.0
            for i in range(3):
                value += weight * su[a][i] * sq[i][b] - qp[a][i] * sr[i][b]
            block[3 + a][3 + b] = value / scale


cdef inline void move_row(const double *step, double *rotation, double *position, double *mu) noexcept nogil:
    """Move one row of a state by `step` (10,), in place: translation, rotation vector applied on the left,
    tensions."""
    cdef int a
    for a in range(3):
        position[a] += step[a]
    rotate_left(rotation, step[3], step[4], step[5])
    for a in range(4):
        mu[a] += step[6 + a]


cdef inline double nan_max(double a, double b) noexcept nogil:
    """np.maximum's: NaN where either is."""
    if a != a or b != b:
        return a + b
    return a if a > b else b


cdef inline double largest_of(const double *values, int count) noexcept nogil:
    """The largest |value| (NaN where any is)."""
    cdef double out = 0.0
    cdef int a
    for a in range(count):
        out = nan_max(out, fabs(values[a]))
    return out


cdef inline double shortening(const double *step, double turn_limit, double shift_limit) noexcept nogil:
    """How many times a step (translation, rotation vector first) exceeds its limits: its turn `turn_limit`
    [rad], its shift `shift_limit` [m]; at least 1 (a step within both is taken whole)."""
    return nan_max(nan_max(largest_of(&step[3], 3) / turn_limit, largest_of(step, 3) / shift_limit), 1.0)


cdef inline double step_size(const double *step, double reach) noexcept nogil:
    """A step's size against the convergence tolerance: translation per `reach`, rotation, tension per |f|."""
    return nan_max(nan_max(largest_of(step, 3) / reach, largest_of(&step[3], 3)), largest_of(&step[6], 4))


cdef int newton_row(const double *lengths, double *rotation, double *position, double *mu, const double *loads,
                    long *steps, const long *taut, int k, const double *attachments, const double *cog,
                    const double *anchors, double scale, double tolerance, int max_steps, double turn_limit,
                    double shift_limit, bint minimum_norm) noexcept nogil:
    """`newton_taut_set` of one row (its (4,) lengths and mu, (3, 3) rotation, (3,) position, (6,) load, the
    plant's (4, 3) attachments and anchors, row-major); returns 1 where converged. Each step solves the
    system exactly (a singular one stops the row) or, `minimum_norm`, by least squares of minimum norm."""
    cdef int size = 6 + k, step, c, j, a, b
    cdef double system[MAX_SIZE][MAX_SIZE]
    cdef double rhs[MAX_SIZE]
    cdef double arm[3]
    cdef double lever[3]
    cdef double unit[3]
    cdef double moment[3]
    cdef double rc[3]
    cdef double block[6][6]
    cdef double rotated_cog[3]
    cdef double norm, weight, largest
    for step in range(max_steps + 1):
        for a in range(MAX_SIZE):
            rhs[a] = 0.0
            for b in range(MAX_SIZE):
                system[a][b] = 0.0
        rotate(rotation, cog, rotated_cog)
        for j in range(k):
            c = taut[j]
            norm = cable_geometry(rotation, position, &attachments[3 * c], &anchors[3 * c], rotated_cog, arm, lever,
                                  unit, moment)
            weight = mu[c]
            for a in range(3):
                rhs[a] += weight * unit[a]
                rhs[3 + a] += weight * moment[a]
            rhs[6 + j] = norm - lengths[c]
            # the Jacobian's row and column of this cable's tension, and of its length equation
            cross3(arm, unit, rc)
            for a in range(3):
                system[a][6 + j] = unit[a]
                system[3 + a][6 + j] = moment[a] / scale
                system[6 + j][a] = unit[a]
                system[6 + j][3 + a] = rc[a]
            pose_block(arm, lever, unit, norm, weight, scale, block)
            for a in range(6):
                for b in range(6):
                    system[a][b] += block[a][b]
        for a in range(3):
            rhs[a] -= loads[a]
            rhs[3 + a] = (rhs[3 + a] - loads[3 + a]) / scale
        if largest_of(rhs, size) < tolerance:  # NaN: never converged
            return 1
        if step == max_steps:
            return 0
        for a in range(size):
            rhs[a] = -rhs[a]
        if least_squares_in_place(system, rhs, size) if minimum_norm else solve_in_place(&system[0][0], MAX_SIZE, rhs, size):
            return 0
        largest = shortening(rhs, turn_limit, shift_limit)
        for a in range(size):
            rhs[a] /= largest
        for a in range(3):
            position[a] += rhs[a]
        rotate_left(rotation, rhs[3], rhs[4], rhs[5])
        for j in range(k):
            mu[taut[j]] += rhs[6 + j]
        steps[0] += 1
    return 0


def newton_taut_set(const double[:, ::1] lengths, double[:, :, ::1] rotation, double[:, ::1] position,
                    double[:, ::1] mu, const double[:, ::1] loads, long[::1] steps, const long[::1] taut,
                    const double[:, ::1] attachments, const double[::1] cog, const double[:, ::1] anchors,
                    double scale, const double[::1] tolerance, int max_steps,
                    unsigned char[::1] converged, double turn_limit, double shift_limit, bint minimum_norm=False):
    """Newton on the taut cables `taut` (k,) of every row until its force and moment balance about C
    (per |f|, moments per `scale`) and its taut spans' lengths are within `tolerance` (n,) of zero,
    at most `max_steps` steps: rotation (n, 3, 3), position (n, 3), mu (n, 4) and steps (n,) are
    moved in place, converged (n,) set. A step is shortened to turn at most `turn_limit` [rad] and
    shift at most `shift_limit` [m]. Each step is the system's exact solution (a row whose system is
    singular stops there, not converged) or, `minimum_norm`, its least-squares solution of minimum norm
    (`least_squares_in_place`: a redundant taut set still moves to its lengths)."""
    cdef Py_ssize_t n = lengths.shape[0], row
    cdef int k = taut.shape[0]
    if 6 + k > MAX_SIZE:
        raise ValueError(f"{k} taut cables: at most 4")
    with nogil:
        for row in range(n):
            converged[row] = newton_row(&lengths[row, 0], &rotation[row, 0, 0], &position[row, 0], &mu[row, 0],
                                        &loads[row, 0], &steps[row], &taut[0], k, &attachments[0, 0], &cog[0],
                                        &anchors[0, 0], scale, tolerance[row], max_steps, turn_limit, shift_limit,
                                        minimum_norm)


cdef int best_exchange(double (*unit)[3], double (*moment)[3], const double *wrench, const long *taut, int k,
                       int cable) noexcept nogil:
    """The taut cable to release so that the set with `cable` instead best holds the (6,) `wrench` (per |f|):
    for each choice the least-squares tensions of its cables' pulls (unit, moment about C), ranked by the
    misfit of the balance plus the most negative tension; the first of equals."""
    cdef double normal[MAX_SIZE][MAX_SIZE]
    cdef double tensions[MAX_SIZE]
    cdef double column[4][6]
    cdef double misfit, best_misfit = INFINITY, residual, value, lowest
    cdef int best = taut[0], o, i, j, r, c
    for o in range(k):
        for j in range(k):
            c = cable if taut[j] == taut[o] else taut[j]
            for r in range(3):
                column[j][r] = unit[c][r]
                column[j][3 + r] = moment[c][r]
        for i in range(k):
            tensions[i] = 0.0
            for r in range(6):
                tensions[i] += column[i][r] * wrench[r]
            for j in range(k):
                normal[i][j] = 0.0
                for r in range(6):
                    normal[i][j] += column[i][r] * column[j][r]
        if solve_in_place(&normal[0][0], MAX_SIZE, tensions, k):
            continue
        residual = 0.0
        lowest = 0.0
        for r in range(6):
            value = -wrench[r]
            for j in range(k):
                value += column[j][r] * tensions[j]
            residual += value * value
        for j in range(k):
            lowest = fmin(lowest, tensions[j])
        misfit = sqrt(residual) - lowest
        if misfit < best_misfit:
            best_misfit = misfit
            best = taut[o]
    return best


def active_set_rows(const double[:, ::1] lengths, double[:, :, ::1] rotation, double[:, ::1] position,
                    double[:, ::1] mu, unsigned char[:, ::1] active, const double[:, ::1] loads, long[::1] steps,
                    unsigned char[::1] done, const double[:, ::1] attachments, const double[::1] cog,
                    const double[:, ::1] anchors, double scale, const double[::1] tolerance, int max_steps,
                    int rounds, double max_turn, const double[::1] rounding, double tension_tol, double turn_limit,
                    double shift_limit):
    """The batched solver's search over taut sets, row by row: Newton (`newton_row`) on the row's set from its
    start pose (rotation, position), then the verdict -- done where converged, turned less than `max_turn`
    from the start, no taut tension below -`tension_tol` and no slack cable longer than its length by more
    than `rounding` (n,); else the next set: a negative tension releases the least loaded cable, an
    overstretched slack cable is taken up (in exchange for the taut cable whose set best holds the load,
    `best_exchange`, when three are taut) -- for at most `rounds` sets, none twice, each of two or three
    cables. In place: a done row's pose, mu, taut set (`active`) and steps; done (n,) set."""
    cdef Py_ssize_t n = lengths.shape[0], row
    cdef int tried[32]
    cdef int count, round_, k, c, j, code, converged, turned, negative, release, cable
    cdef long taut[4]
    cdef unsigned char nxt[4]
    cdef double start_rotation[9]
    cdef double start_position[3]
    cdef double rotated_cog[3]
    cdef double arm[4][3]
    cdef double lever[4][3]
    cdef double unit[4][3]
    cdef double moment[4][3]
    cdef double over[4]
    cdef double norm, cosine, lowest, largest
    if rounds > 32:
        raise ValueError(f"{rounds} rounds: at most 32")
    with nogil:
        for row in range(n):
            for j in range(9):
                start_rotation[j] = (&rotation[row, 0, 0])[j]
            for j in range(3):
                start_position[j] = position[row, j]
            count = 0
            for round_ in range(rounds):
                code = 0
                k = 0
                for c in range(4):
                    if active[row, c]:
                        code |= 1 << c
                        taut[k] = c
                        k += 1
                tried[count] = code
                count += 1
                if k != 2 and k != 3:  # four taut (nearly singular) or one taut (single-cable test): per sample
                    break
                for j in range(9):
                    (&rotation[row, 0, 0])[j] = start_rotation[j]
                for j in range(3):
                    position[row, j] = start_position[j]
                converged = newton_row(&lengths[row, 0], &rotation[row, 0, 0], &position[row, 0], &mu[row, 0],
                                       &loads[row, 0], &steps[row], taut, k, &attachments[0, 0], &cog[0],
                                       &anchors[0, 0], scale, tolerance[row], max_steps, turn_limit, shift_limit,
                                       False)
                rotate(&rotation[row, 0, 0], &cog[0], rotated_cog)
                cable = 0
                largest = -INFINITY
                for c in range(4):
                    norm = cable_geometry(&rotation[row, 0, 0], &position[row, 0], &attachments[c, 0],
                                          &anchors[c, 0], rotated_cog, arm[c], lever[c], unit[c], moment[c])
                    over[c] = -INFINITY if active[row, c] else norm - lengths[row, c]
                    if over[c] > largest:
                        largest = over[c]
                        cable = c
                cosine = -1.0
                for j in range(9):
                    cosine += (&rotation[row, 0, 0])[j] * start_rotation[j]
                turned = acos(fmin(fmax(cosine / 2.0, -1.0), 1.0)) >= max_turn
                lowest = INFINITY
                release = taut[0]
                for j in range(k):
                    if mu[row, taut[j]] < lowest:
                        lowest = mu[row, taut[j]]
                        release = taut[j]
                negative = lowest < -tension_tol
                if converged and not turned and not negative and not largest > rounding[row]:
                    done[row] = 1
                    break
                for c in range(4):
                    nxt[c] = active[row, c] if converged else 0
                if converged and negative:
                    nxt[release] = 0
                elif converged and largest > 0.0:
                    nxt[cable] = 1
                    if k >= 3:
                        nxt[best_exchange(unit, moment, &loads[row, 0], taut, k, cable)] = 0
                code = 0
                for c in range(4):
                    active[row, c] = nxt[c]
                    if not nxt[c]:
                        mu[row, c] = 0.0
                    else:
                        code |= 1 << c
                if code == 0:
                    break
                for j in range(count):
                    if tried[j] == code:
                        code = 0
                if code == 0:
                    break


def slack_pin_bounds(const long[::1] samples, const long[::1] codes, const long[::1] ropes,
                     const double[:, ::1] deviation, const double[:, :, ::1] covariance, double[::1] bound):
    """For each candidate (its sample and taut-set code, bit i for rope i), the quadratic form d^T C^-1 d of the
    load pins on the ropes it leaves slack: d their readings' deviation from the pins' expected error
    (`deviation` (N, k) for the ropes with a pin, `ropes` (k,); NaN where not read, left out), C their block of
    the sample's pin covariance (N, 4, 4). Zero where it leaves no pinned rope slack."""
    cdef Py_ssize_t n = samples.shape[0], i
    cdef int k = ropes.shape[0], m, a, b, s
    cdef int picked[4]
    cdef double system[MAX_SIZE][MAX_SIZE]
    cdef double d[MAX_SIZE]
    cdef double x[MAX_SIZE]
    cdef double value
    at_most_four_pins(k)
    with nogil:
        for i in range(n):
            s = samples[i]
            m = 0
            for a in range(k):
                if not (codes[i] >> ropes[a]) & 1:
                    picked[m] = a
                    m += 1
            bound[i] = 0.0
            if m == 0:
                continue
            for a in range(m):
                value = deviation[s, picked[a]]
                d[a] = value if value == value else 0.0
                x[a] = d[a]
                for b in range(m):
                    if value == value and deviation[s, picked[b]] == deviation[s, picked[b]]:
                        system[a][b] = covariance[s, ropes[picked[a]], ropes[picked[b]]]
                    else:
                        system[a][b] = 1.0 if a == b else 0.0
            if solve_in_place(&system[0][0], MAX_SIZE, x, m):
                bound[i] = INFINITY
                continue
            value = 0.0
            for a in range(m):
                value += d[a] * x[a]
            bound[i] = value


def elastic_newton_rows(const double[:, ::1] lengths, double[:, :, ::1] rotation, double[:, ::1] position,
                        const double[:, ::1] loads, const double[:, ::1] stiffness, const double[::1] weight,
                        const double[:, ::1] attachments, const double[::1] cog, const double[:, ::1] anchors,
                        double scale, int max_steps, double tol, double rounding_tol, double step_turn,
                        double[:, ::1] tensions, double[:, ::1] stretch, long[::1] steps, unsigned char[::1] done):
    """Newton on the force and moment balance of every row on elastic ropes (`stiffness` EA / l (n, 4) [N/m]; a
    rope pulls where its span exceeds its unstretched length), from the row's pose, until the balance per
    `weight` |f| (moments per `scale`) is within `tol` (or within `rounding_tol` after a step below 1e-13):
    the pose, tensions, stretch and steps of each converged row, done (n,) set. A step is shortened to turn at
    most `step_turn` [rad] and shift at most `step_turn` moment scales; a platform on no stretched rope is
    lowered by a thousandth of its shortest rope. A row whose system is singular (a pivot below 1e-14 of its
    largest entry, as the per-sample solver's least squares cuts: one rope pulling leaves the turn about it
    free) stops there, not done."""
    cdef Py_ssize_t n = lengths.shape[0], row
    cdef int it, c, a, b, pulling
    cdef double system[MAX_SIZE][MAX_SIZE]
    cdef double delta[MAX_SIZE]
    cdef double arm[4][3]
    cdef double lever[4][3]
    cdef double unit[4][3]
    cdef double moment[4][3]
    cdef double twist[4][3]
    cdef double norm[4]
    cdef double rotated_cog[3]
    cdef double sum_arm[3]
    cdef double sum_lever[3]
    cdef double left[6]
    cdef double right[6]
    cdef double residual[6]
    cdef double tension[4]
    cdef double turn, along, largest, last_step, shortest, longest, diagonal, biggest
    with nogil:
        for row in range(n):
            last_step = INFINITY
            shortest = lengths[row, 0]
            longest = lengths[row, 0]
            for c in range(1, 4):
                shortest = fmin(shortest, lengths[row, c])
                longest = fmax(longest, lengths[row, c])
            for it in range(max_steps):
                rotate(&rotation[row, 0, 0], &cog[0], rotated_cog)
                for a in range(6):
                    residual[a] = 0.0
                pulling = 0
                for c in range(4):
                    norm[c] = cable_geometry(&rotation[row, 0, 0], &position[row, 0], &attachments[c, 0],
                                             &anchors[c, 0], rotated_cog, arm[c], lever[c], unit[c], moment[c])
                    stretch[row, c] = fmax(norm[c] - lengths[row, c], 0.0)
                    tension[c] = stiffness[row, c] * stretch[row, c]
                    if stretch[row, c] > 0.0:
                        pulling = 1
                    for a in range(3):
                        residual[a] += tension[c] * unit[c][a]
                        residual[3 + a] += tension[c] * moment[c][a]
                for a in range(3):
                    residual[a] = (residual[a] - loads[row, a]) / weight[row]
                    residual[3 + a] = (residual[3 + a] - loads[row, 3 + a]) / scale / weight[row]
                largest = largest_of(residual, 6)
                if largest < tol or (last_step < 1e-13 and largest < rounding_tol):
                    for c in range(4):
                        tensions[row, c] = tension[c]
                    done[row] = 1
                    break
                for a in range(6):
                    delta[a] = -residual[a] if pulling else 0.0  # no rope pulling: lowered below, not solved
                    for b in range(6):
                        system[a][b] = 0.0
                if pulling:
                    for a in range(3):
                        sum_arm[a] = 0.0
                        sum_lever[a] = 0.0
                    diagonal = 0.0
                    for c in range(4):
                        cross3(arm[c], unit[c], twist[c])
                        turn = tension[c] / norm[c]
                        along = (stiffness[row, c] if stretch[row, c] > 0.0 else 0.0) - turn
                        for a in range(3):
                            left[a] = unit[c][a]
                            left[3 + a] = moment[c][a]
                            right[a] = unit[c][a]
                            right[3 + a] = twist[c][a]
                        for a in range(6):
                            for b in range(6):
                                system[a][b] += along * left[a] * right[b]
                        for a in range(3):
                            for b in range(3):  # -t r q^T + tau q u^T
                                system[3 + a][3 + b] += -turn * arm[c][a] * lever[c][b] + tension[c] * lever[c][a] * unit[c][b]
                            system[a][a] += turn
                            sum_arm[a] += turn * arm[c][a]
                            sum_lever[a] += turn * lever[c][a]
                        diagonal += turn * (lever[c][0] * arm[c][0] + lever[c][1] * arm[c][1] + lever[c][2] * arm[c][2]) \
                            - tension[c] * (lever[c][0] * unit[c][0] + lever[c][1] * unit[c][1] + lever[c][2] * unit[c][2])
                    # - [sum t r]x in the force's turn, + [sum t q]x in the moment's shift
                    system[0][4] += sum_arm[2]
                    system[0][5] -= sum_arm[1]
                    system[1][3] -= sum_arm[2]
                    system[1][5] += sum_arm[0]
                    system[2][3] += sum_arm[1]
                    system[2][4] -= sum_arm[0]
                    system[3][1] -= sum_lever[2]
                    system[3][2] += sum_lever[1]
                    system[4][0] += sum_lever[2]
                    system[4][2] -= sum_lever[0]
                    system[5][0] -= sum_lever[1]
                    system[5][1] += sum_lever[0]
                    for a in range(3):
                        system[3 + a][3 + a] += diagonal
                    biggest = 0.0  # the system's largest entry: a pivot 1e-14 of it is taken as zero (rank deficient)
                    for a in range(6):
                        for b in range(6):
                            if a >= 3:
                                system[a][b] /= scale
                            system[a][b] /= weight[row]
                            biggest = fmax(biggest, fabs(system[a][b]))
                    if solve_in_place(&system[0][0], MAX_SIZE, delta, 6, 1e-14 * biggest):
                        break
                largest = shortening(delta, step_turn, step_turn * scale)
                for a in range(6):
                    delta[a] /= largest
                if not pulling:
                    delta[2] = -1e-3 * shortest
                else:
                    last_step = nan_max(largest_of(delta, 3) / longest, largest_of(&delta[3], 3))
                for a in range(3):
                    position[row, a] += delta[a]
                rotate_left(&rotation[row, 0, 0], delta[3], delta[4], delta[5])
                steps[row] += 1


cdef inline void unstretched(double span, double tension, double ea, double weight, double *length,
                             double *d_span, double *d_tension) noexcept nogil:
    """ropes.Ropes.unstretched of one rope (ea <= 0: rigid)."""
    cdef double factor, effective, root, d_effective
    if ea <= 0.0:
        length[0] = span
        d_span[0] = 1.0
        d_tension[0] = 0.0
        return
    factor = 1.0 + tension / ea
    effective = span / factor
    if weight > 0.0:
        root = sqrt(1.0 + 2.0 * weight * effective / ea)
        length[0] = 2.0 * effective / (1.0 + root)
        d_effective = 1.0 / (1.0 + weight * length[0] / ea)
    else:
        length[0] = effective
        d_effective = 1.0
    d_span[0] = d_effective / factor
    d_tension[0] = -d_effective * effective / (ea * factor)


def equilibrium_terms(const double[:, :, ::1] rotation, const double[:, ::1] position, const double[:, ::1] mu,
                      const unsigned char[:, ::1] taut, const double[::1] weight, const double[:, ::1] lengths,
                      const double[:, :, ::1] anchors, const double[:, ::1] attachments, const double[::1] cog,
                      const double[:, ::1] loads, const double[::1] axial_stiffness, double rope_weight,
                      double scale, double sigma, double[:, ::1] residual, double[:, ::1] constraint,
                      double[:, :, ::1] jacobian, double[:, :, ::1] balance, bint with_jacobian):
    """The fusion's rope terms of n rows of state (rotation, position, mu = tau / |f|, taut set; each row's
    |f| `weight`, expected lengths, anchors (n, 4, 3) and load per |f|): each rope's length residual
    (residual (n, 4): a taut rope's unstretched length through the rope law, a slack one's excess over its
    expected length, per `sigma`), the force and moment imbalance (constraint (n, 6), moments per `scale`)
    and, `with_jacobian`, the length rows' derivative (jacobian (n, 4, 10): position, rotation vector on
    the left, mu) and the balance's (balance (n, 6, 10)). EA (4,) <= 0: rigid ropes of weight 0."""
    cdef Py_ssize_t n = rotation.shape[0], row
    cdef int c, a, b
    cdef double arm[3]
    cdef double lever[3]
    cdef double unit[3]
    cdef double moment[3]
    cdef double arm_unit[3]
    cdef double rotated_cog[3]
    cdef double block[6][6]
    cdef double norm, m, held, length, d_span, d_tension, slack_length, d_slack, d_none, excess, d_pose
    with nogil:
        for row in range(n):
            for a in range(6):
                constraint[row, a] = 0.0
                if with_jacobian:
                    for b in range(10):
                        balance[row, a, b] = 0.0
            rotate(&rotation[row, 0, 0], &cog[0], rotated_cog)
            for c in range(4):
                norm = cable_geometry(&rotation[row, 0, 0], &position[row, 0], &attachments[c, 0], &anchors[row, c, 0],
                                      rotated_cog, arm, lever, unit, moment)
                m = mu[row, c]
                for a in range(3):
                    constraint[row, a] += m * unit[a]
                    constraint[row, 3 + a] += m * moment[a]
                unstretched(norm, m * weight[row], axial_stiffness[c], rope_weight, &length, &d_span, &d_tension)
                unstretched(norm, 0.0, axial_stiffness[c], rope_weight, &slack_length, &d_slack, &d_none)
                excess = slack_length - lengths[row, c]
                if taut[row, c]:
                    residual[row, c] = (length - lengths[row, c]) / sigma
                    d_pose = d_span / sigma
                else:
                    residual[row, c] = (excess if excess > 0.0 else 0.0) / sigma
                    d_pose = d_slack / sigma if excess > 0.0 else 0.0
                if not with_jacobian:
                    continue
                cross3(arm, unit, arm_unit)
                for a in range(3):
                    jacobian[row, c, a] = d_pose * unit[a]
                    jacobian[row, c, 3 + a] = d_pose * arm_unit[a]
                for a in range(4):
                    jacobian[row, c, 6 + a] = 0.0
                if taut[row, c]:
                    jacobian[row, c, 6 + c] = d_tension * weight[row] / sigma
                    for a in range(3):
                        balance[row, a, 6 + c] = unit[a]
                        balance[row, 3 + a, 6 + c] = moment[a] / scale
                    held = m
                else:
                    held = 0.0
                pose_block(arm, lever, unit, norm, held, scale, block)
                for a in range(6):
                    for b in range(6):
                        balance[row, a, b] += block[a][b]
            for a in range(3):
                constraint[row, a] -= loads[row, a]
                constraint[row, 3 + a] = (constraint[row, 3 + a] - loads[row, 3 + a]) / scale


def kkt_systems(const double[:, :, ::1] jacobian, const double[:, ::1] residual, const double[:, :, ::1] balance,
                const unsigned char[:, ::1] slack, const double[:, ::1] mu, double eps, double[:, :, ::1] system,
                double[:, ::1] gradient):
    """The rows' 16 x 16 KKT systems of the Gauss-Newton model (jacobian (n, M, 10), residual (n, M)) with
    the balance (n, 6, 10) linearised, and the cost's gradient (n, 10): a slack rope's tension held (an
    identity row, its gradient the tension, so a step sets it to zero), a Levenberg term `eps` on the state."""
    cdef Py_ssize_t n = jacobian.shape[0], rows = jacobian.shape[1], row, r
    cdef int a, b
    cdef bint held_a
    cdef double value
    with nogil:
        for row in range(n):
            for a in range(16):
                for b in range(16):
                    system[row, a, b] = 0.0
            for a in range(10):
                held_a = a >= 6 and slack[row, a - 6]
                for b in range(10):
                    if held_a or (b >= 6 and slack[row, b - 6]):
                        system[row, a, b] = 1.0 if (a == b and held_a) else 0.0
                        continue
                    value = 0.0
                    for r in range(rows):
                        value += jacobian[row, r, a] * jacobian[row, r, b]
                    system[row, a, b] = value + (eps if a == b else 0.0)
                if held_a:
                    gradient[row, a] = mu[row, a - 6]
                else:
                    value = 0.0
                    for r in range(rows):
                        value += jacobian[row, r, a] * residual[row, r]
                    gradient[row, a] = value
                for b in range(6):
                    system[row, a, 10 + b] = balance[row, b, a]
                    system[row, 10 + b, a] = balance[row, b, a]


def kkt_steps(const double[:, :, ::1] system, const double[:, ::1] rhs, double[:, ::1] step,
              unsigned char[::1] singular):
    """Each row's KKT system (n, 16, 16) solved for its right-hand side (n, 16) into `step`, by Gaussian
    elimination with partial pivoting (as LAPACK's gesv, row by row: numpy's batched solve cost the lab
    robot's replay a quarter of its estimating process); a row whose system has a zero pivot is flagged in
    `singular` (its step left as it was) for the caller to solve by least squares."""
    cdef Py_ssize_t n = system.shape[0], row
    cdef int a, b
    cdef double work[KKT_SIZE][KKT_SIZE]
    cdef double x[KKT_SIZE]
    with nogil:
        for row in range(n):
            for a in range(KKT_SIZE):
                x[a] = rhs[row, a]
                for b in range(KKT_SIZE):
                    work[a][b] = system[row, a, b]
            singular[row] = solve_in_place(&work[0][0], KKT_SIZE, x, KKT_SIZE)
            if not singular[row]:
                for a in range(KKT_SIZE):
                    step[row, a] = x[a]


def kkt_responses(const double[:, :, ::1] system, const double[:, :, ::1] rhs, double[:, :, ::1] out,
                  unsigned char[::1] singular):
    """Each row's KKT system (n, 16, 16) solved for its k right-hand sides (n, 16, k) into `out` (`solve_in_place`:
    one elimination a row, applied to every column: a window's parameters and model error at once, where numpy's
    batched solve spent 5 us a row, the most of the model error's and the tracked parameters' updates); a row
    with a zero pivot is flagged in `singular` (its columns left part-eliminated)."""
    cdef Py_ssize_t n = system.shape[0], k = rhs.shape[2], row, c
    cdef int a, b
    cdef double work[KKT_SIZE][KKT_SIZE]
    with nogil:
        for row in range(n):
            for a in range(KKT_SIZE):
                for b in range(KKT_SIZE):
                    work[a][b] = system[row, a, b]
                for c in range(k):
                    out[row, a, c] = rhs[row, a, c]
            singular[row] = solve_in_place(&work[0][0], KKT_SIZE, &out[row, 0, 0], KKT_SIZE, 0.0, <int>k)


cdef int at_most_four_pins(Py_ssize_t k) except -1:
    """ValueError where a row would have more load pins than ropes."""
    if k > 4:
        raise ValueError(f"{k} load pins: at most 4")
    return 0


cdef inline void whiten_column(double *column, Py_ssize_t stride, const double *length_white, const double *pin_white,
                               const long *pins, const double *pin_scale, const double *offset, int k) noexcept nogil:
    """One column of a row -- its residuals, or one column of their Jacobian: items `stride` apart -- weighed in
    place: its four length entries by the lengths' whitening (4 x 4), its pins' entries (rows `pins`, times
    `pin_scale`, plus `offset`) by the pins' whitening (k x k)."""
    cdef double out[4]
    cdef double raw[4]
    cdef double value
    cdef int a, b
    for a in range(4):
        out[a] = 0.0
        for b in range(4):
            out[a] += length_white[4 * a + b] * column[b * stride]
    for a in range(4):
        column[a * stride] = out[a]
    for a in range(k):
        raw[a] = column[pins[a] * stride] * pin_scale[a] + offset[a]
    for a in range(k):
        value = 0.0
        for b in range(k):
            value += pin_white[k * a + b] * raw[b]
        column[pins[a] * stride] = value


def whiten_rows(const long[::1] sample, double[:, ::1] residual, double[:, :, ::1] jacobian, bint with_jacobian,
                const double[:, :, ::1] length_white, const double[:, :, ::1] pin_white, const long[::1] pins,
                const double[::1] pin_scale, const unsigned char[:, ::1] measured, const double[:, ::1] expected):
    """Weigh each row's length and load-pin residuals (and, `with_jacobian`, their Jacobian rows) by its sample's
    prior, in place: the lengths' deviations [m] by the whitening (N, 4, 4) of the corrections' covariance; the
    pins' columns `pins` (k,), read as (predicted - measured) / `pin_scale`, as what the pins read beyond the
    model's prediction and their `expected` error (N, k) where `measured` (N, k), by the pins' whitening
    (N, k, k)."""
    cdef Py_ssize_t n = residual.shape[0], row, col
    cdef int k = pins.shape[0], a, s
    cdef double offset[4]
    cdef double nothing[4]
    cdef const double *pin_block = NULL
    at_most_four_pins(k)
    for a in range(4):
        nothing[a] = 0.0
    with nogil:
        for row in range(n):
            s = sample[row]
            if k:
                pin_block = &pin_white[s, 0, 0]
            for a in range(k):
                offset[a] = expected[s, a] if measured[s, a] else 0.0
            whiten_column(&residual[row, 0], 1, &length_white[s, 0, 0], pin_block, &pins[0] if k else NULL,
                          &pin_scale[0] if k else NULL, offset, k)
            if not with_jacobian:
                continue
            for col in range(jacobian.shape[2]):
                whiten_column(&jacobian[row, 0, col], jacobian.shape[2], &length_white[s, 0, 0], pin_block,
                              &pins[0] if k else NULL, &pin_scale[0] if k else NULL, nothing, k)


def gauss_newton_verdict(const long[::1] live, const double[::1] cost, const double[:, ::1] constraint,
                         const double[::1] reach, double[::1] previous, double[:, ::1] last, double[::1] scale,
                         unsigned char[::1] settled, double[:, :, ::1] rotation, double[:, ::1] position,
                         double[:, ::1] mu, double balance_tol, double cost_tol, double step_tol, long[::1] kept,
                         long[::1] retry):
    """The fusion's Gauss-Newton, after its rows `live` were evaluated (their cost, the sum of squared residuals,
    and their imbalance `constraint` (n, 6)): a balanced row whose cost rose takes half its last step back
    (its step scale halved; settled where that half is below `step_tol`, else retried); a balanced row that
    went too far before and whose cost has stopped falling is settled; the others go on to a step. Their
    positions among `live` go to `kept`, the rows retried to `retry`; returns how many of each."""
    cdef Py_ssize_t n = live.shape[0], j
    cdef long row, count = 0, retried = 0
    cdef int a
    cdef double value
    cdef bint balanced
    cdef double back[10]
    with nogil:
        for j in range(n):
            row = live[j]
            balanced = largest_of(&constraint[j, 0], 6) < balance_tol * reach[row]
            value = cost[j] if balanced else INFINITY
            if balanced and value > previous[row] * (1.0 + 1e-12) + 1e-12:  # past the minimum: half back
                for a in range(10):
                    back[a] = -0.5 * last[row, a]
                move_row(back, &rotation[row, 0, 0], &position[row, 0], &mu[row, 0])
                for a in range(10):
                    last[row, a] *= 0.5
                scale[row] *= 0.5
                if step_size(&last[row, 0], reach[row]) < step_tol:
                    settled[row] = 1
                else:
                    retry[retried] = row
                    retried += 1
                continue
            balanced = balanced and scale[row] < 1.0 and fabs(previous[row] - value) <= cost_tol * (1.0 + value)
            previous[row] = value
            if balanced:  # went too far before, and has stopped falling on the balance
                settled[row] = 1
                continue
            kept[count] = j
            count += 1
    return count, retried


def gauss_newton_advance(const long[::1] live, const double[:, ::1] step, const long[::1] retry,
                         const double[::1] reach, const double[::1] scale, double[:, ::1] last, long[::1] steps,
                         unsigned char[::1] settled, double[:, :, ::1] rotation, double[:, ::1] position,
                         double[:, ::1] mu, double turn_limit, double shift_limit, double step_tol, long[::1] out):
    """Take each row's Gauss-Newton step (the first ten columns of `step`, (n, >= 10)), shortened to turn at most
    `turn_limit` [rad] and shift at most `shift_limit` [m] and scaled by the row's step scale; a row whose step
    was below `step_tol` is settled. The rows still moving, then those retried, go to `out`; returns how many."""
    cdef Py_ssize_t n = live.shape[0], j
    cdef long row, count = 0
    cdef int a
    cdef double size, factor
    cdef double moved[10]
    with nogil:
        for j in range(n):
            row = live[j]
            size = step_size(&step[j, 0], reach[row])
            factor = scale[row] / shortening(&step[j, 0], turn_limit, shift_limit)
            for a in range(10):
                moved[a] = step[j, a] * factor
                last[row, a] = moved[a]
            move_row(moved, &rotation[row, 0, 0], &position[row, 0], &mu[row, 0])
            steps[row] += 1
            if size < step_tol:
                settled[row] = 1
            elif size >= step_tol:
                out[count] = row
                count += 1
        for j in range(retry.shape[0]):
            out[count] = retry[j]
            count += 1
    return count