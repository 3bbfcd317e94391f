/* The forecaster's one hot loop: moving every tracked object along the activity paths.
 *
 * For each level of the paths' prefix trees (globe/inference/forecast.py, Forecaster._propagate)
 * every (path node x object) reads its hazard of leaving its place, adds what leaves to its
 * query's departures and to its (query, activity left) group's sums, and keeps what survives
 * (level()); then each group's sums times each object's destinations are added to its query's
 * destinations (destinations()). This is the only implementation of that arithmetic: numpy spent
 * its time allocating (node x object) temporaries here. Every index read from an argument is
 * checked before it is used: a bad input raises ValueError, never a read out of bounds.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

/* -- buffers ------------------------------------------------------------------------------------- */

#define KERNEL "propagate"
#include "_arrays.h"

/* The same, and it must hold exactly `n` items. */
static int buf_sized(PyObject *obj, Buf *b, Kind kind, int writable, Py_ssize_t n, const char *what) {
    if (buf_get(obj, b, kind, writable, what) < 0) return -1;
    if (b->n != n) {
        PyErr_Format(PyExc_ValueError, KERNEL ": %s holds %zd items, expected %zd", what, b->n, n);
        return -1;
    }
    return 0;
}

#define F64P(b) ((double *)(b).view.buf)
#define I64P(b) ((const int64_t *)(b).view.buf)
#define BOOLP(b) ((const char *)(b).view.buf)

static int bad(const char *what) {
    PyErr_Format(PyExc_ValueError, KERNEL ": %s out of range", what);
    return -1;
}

/* a * b, or -1 (ValueError set) where either is negative or the product overflows: sizes built
 * from the caller's dimensions are checked before any buffer is compared with them. */
static Py_ssize_t times(Py_ssize_t a, Py_ssize_t b) {
    if (a < 0 || b < 0 || (b && a > PY_SSIZE_T_MAX / b)) return bad("a size");
    return a * b;
}

/* -- hazards of one level ------------------------------------------------------------------------ */

enum { M_HAZARD, M_P1, M_SWITCH_INDEX, M_SWITCH_SEEN, M_SWITCH_MOVED, M_CELLS, M_SEEN, M_EARLIER, M_COUNT };
enum { L_QUERY, L_UP, L_DUR, L_ENDS, L_FIRST, L_ACT, L_PARENT, L_WEIGHT, L_GROUP, L_COUNT };

typedef struct {
    Py_ssize_t na, nc, ne, nm, npairs, nj, nq, nsw;
    double k;
    int switching, all_seen;
} Shape;

/* The hazards of every object for node n (owner q, parent activity a) into h[0..nj): the hazard
 * of (activity, steps into its run, whether it ends, moved earlier in the run, object, place),
 * shrunk towards the switch to the activity that starts where the run ends and switches are
 * counted; P(move | activity, object) for an object never seen at its place (check_model has
 * checked every cell). */
static int hazards_of(const Shape *s, Buf *m, Buf *l, Py_ssize_t n, int64_t q, int64_t a, double *h) {
    const double *p1 = F64P(m[M_P1]) + a * s->nj;
    const char *seen = BOOLP(m[M_SEEN]) + q * s->nj;
    if (s->npairs == 0) {
        memcpy(h, p1, (size_t)s->nj * sizeof(double));
        return 0;
    }
    int64_t d = I64P(l[L_DUR])[n];
    if (d < 0) return bad("a run duration");
    if (d > s->nc - 1) d = s->nc - 1;
    int64_t e = s->ne == 2 ? (BOOLP(l[L_ENDS])[n] != 0) : 0;
    int64_t base = ((a * s->nc + d) * s->ne + e) * s->nm; /* (activity, duration, end, moved = 0) */
    int first = s->nm == 2 && BOOLP(l[L_FIRST])[n];
    const char *earlier = BOOLP(m[M_EARLIER]) + q * s->nj;
    const int64_t *cells = I64P(m[M_CELLS]) + q * s->nj;
    const double *hazard = F64P(m[M_HAZARD]);
    int64_t r = -1; /* the switch row of (a, the activity that starts), when the run ends */
    if (s->switching && e) {
        int64_t b = I64P(l[L_ACT])[n];
        if (b < 0 || b >= s->na) return bad("an activity");
        r = I64P(m[M_SWITCH_INDEX])[a * s->na + b];
        if (r >= s->nsw) return bad("a switch row");
    }
    const double *sw_moved = r >= 0 ? F64P(m[M_SWITCH_MOVED]) + r * s->npairs : NULL;
    const double *sw_seen = r >= 0 ? F64P(m[M_SWITCH_SEEN]) + r * s->npairs : NULL;
    for (Py_ssize_t j = 0; j < s->nj; j++) {
        if (!s->all_seen && !seen[j]) { /* never seen at its place: P(move | activity, object) */
            h[j] = p1[j];
            continue;
        }
        int64_t cell = cells[j];
        double x = hazard[(base + (first && earlier[j])) * s->npairs + cell];
        if (sw_moved) x = (sw_moved[cell] + s->k * x) / (sw_seen[cell] + s->k);
        h[j] = x;
    }
    return 0;
}

static int check_model(Shape *s, Buf *m) {
    if (s->na < 1 || s->nc < 1 || (s->ne != 1 && s->ne != 2) || (s->nm != 1 && s->nm != 2) || s->npairs < 0 || s->nj < 0)
        return bad("a hazard table's shape");
    Py_ssize_t size = times(times(times(times(s->na, s->nc), s->ne), s->nm), s->npairs), p1 = times(s->na, s->nj);
    Py_ssize_t cells = times(s->nq, s->nj), switches = times(s->na, s->na);
    if (size < 0 || p1 < 0 || cells < 0 || switches < 0) return -1;
    if (m[M_HAZARD].n != size) return bad("the hazard table's size");
    if (m[M_P1].n != p1) return bad("the activity-object hazards' size");
    s->nsw = s->npairs ? m[M_SWITCH_SEEN].n / s->npairs : 0;
    s->switching = s->ne == 2 && m[M_SWITCH_INDEX].n > 0;
    if (s->switching && (m[M_SWITCH_INDEX].n != switches || m[M_SWITCH_SEEN].n != s->nsw * s->npairs ||
                         m[M_SWITCH_MOVED].n != m[M_SWITCH_SEEN].n))
        return bad("the switch tables' sizes");
    if (m[M_CELLS].n != cells || m[M_SEEN].n != cells || m[M_EARLIER].n != cells)
        return bad("the cells' or the seen or earlier flags' size");
    s->all_seen = 1;
    for (Py_ssize_t i = 0; i < m[M_SEEN].n; i++)
        if (!BOOLP(m[M_SEEN])[i]) {
            s->all_seen = 0;
            break;
        }
    for (Py_ssize_t i = 0; i < m[M_CELLS].n && s->npairs; i++)
        if (I64P(m[M_CELLS])[i] < 0 || I64P(m[M_CELLS])[i] >= s->npairs) return bad("an (object, place) cell");
    return 0;
}

static const Kind model_kinds[M_COUNT] = {F64, F64, I64, F64, F64, I64, BOOL, BOOL};
static const char *model_names[M_COUNT] = {"hazard", "p1", "switch_index", "switch_seen", "switch_moved",
                                           "cells", "seen", "earlier"};
static const Kind level_kinds[L_COUNT] = {I64, I64, I64, BOOL, BOOL, I64, I64, F64, I64};
static const char *level_names[L_COUNT] = {"query", "up", "dur_up", "ends", "first_up", "act", "parent", "weight", "group"};

static int get_all(PyObject *tuple, Buf *out, const Kind *kinds, const char **names, int count, const char *what) {
    if (!PyTuple_Check(tuple) || PyTuple_GET_SIZE(tuple) != count) {
        PyErr_Format(PyExc_ValueError, "propagate: %s must be a tuple of %d arrays", what, count);
        return -1;
    }
    for (int i = 0; i < count; i++)
        if (buf_get(PyTuple_GET_ITEM(tuple, i), &out[i], kinds[i], 0, names[i]) < 0) return -1;
    return 0;
}

/* One node: what leaves (weight * survive * h) added to its query's departures and its group's
 * sums, and what survives (survive * (1 - h)). The rows never overlap (restrict: vectorised). */
static void spread(Py_ssize_t nj, double weight, const double *restrict h, const double *restrict before,
                   double *restrict departure, double *restrict sums, double *restrict after) {
    for (Py_ssize_t j = 0; j < nj; j++) {
        double leave = weight * before[j] * h[j];
        departure[j] += leave;
        sums[j] += leave;
        after[j] = before[j] * (1.0 - h[j]);
    }
}

/* level((activities, durations, ends, memory, cells, objects, queries, steps), k, model, level,
 *       survive_up, survive, per, departure, step)
 *   model: M_COUNT arrays; level: L_COUNT arrays over its nodes (activities already the movement
 *   model's). Writes survive (nodes x objects), adds to per ((query, activity left) groups x
 *   objects) and to departure (queries x steps x objects) at `step`, node by node. */
static PyObject *level(PyObject *self, PyObject *args) {
    PyObject *model, *lv, *o_up, *o_surv, *o_per, *o_dep;
    Shape s;
    Py_ssize_t nsteps, step;
    if (!PyArg_ParseTuple(args, "(nnnnnnnn)dOOOOOOn", &s.na, &s.nc, &s.ne, &s.nm, &s.npairs, &s.nj, &s.nq, &nsteps, &s.k,
                          &model, &lv, &o_up, &o_surv, &o_per, &o_dep, &step))
        return NULL;
    Buf m[M_COUNT] = {0}, l[L_COUNT] = {0}, up = {0}, surv = {0}, per = {0}, dep = {0};
    PyObject *result = NULL;
    double *h = NULL;
    if (get_all(model, m, model_kinds, model_names, M_COUNT, "model") < 0 || check_model(&s, m) < 0) goto done;
    if (get_all(lv, l, level_kinds, level_names, L_COUNT, "level") < 0) goto done;
    Py_ssize_t n = l[L_QUERY].n, nj = s.nj;
    for (int i = 0; i < L_COUNT; i++)
        if (l[i].n != n) {
            bad("a level array's length");
            goto done;
        }
    if (step < 0 || step >= nsteps) {
        bad("the step");
        goto done;
    }
    Py_ssize_t n_after = times(n, nj), n_dep = times(times(s.nq, nsteps), nj);
    if (n_after < 0 || n_dep < 0 || buf_get(o_up, &up, F64, 0, "survive_up") < 0 ||
        buf_sized(o_surv, &surv, F64, 1, n_after, "survive") < 0 || buf_get(o_per, &per, F64, 1, "per") < 0 ||
        buf_sized(o_dep, &dep, F64, 1, n_dep, "departure") < 0)
        goto done;
    Py_ssize_t nup = nj ? up.n / nj : 0, ngroups = nj ? per.n / nj : 0;
    if (up.n != nup * nj || per.n != ngroups * nj) {
        bad("survive_up's or per's size");
        goto done;
    }
    const int64_t *query = I64P(l[L_QUERY]), *act_up = I64P(l[L_UP]), *parent = I64P(l[L_PARENT]), *group = I64P(l[L_GROUP]);
    const double *weight = F64P(l[L_WEIGHT]), *survive_up = F64P(up);
    double *survive = F64P(surv), *sums = F64P(per), *departure = F64P(dep);
    h = PyMem_Malloc((size_t)(nj ? nj : 1) * sizeof(double));
    if (h == NULL) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        int64_t q = query[i], a = act_up[i], p = parent[i], g = group[i];
        if (q < 0 || q >= s.nq || a < 0 || a >= s.na || (nj && (p < 0 || p >= nup || g < 0 || g >= ngroups))) {
            bad("a node's query, activity, parent or group");
            goto done;
        }
        if (hazards_of(&s, m, l, i, q, a, h) < 0) goto done;
        spread(nj, weight[i], h, survive_up + p * nj, departure + (q * nsteps + step) * nj, sums + g * nj, survive + i * nj);
    }
    result = Py_NewRef(Py_None);
done:
    PyMem_Free(h);
    for (int i = 0; i < M_COUNT; i++) buf_release(&m[i]);
    for (int i = 0; i < L_COUNT; i++) buf_release(&l[i]);
    buf_release(&up);
    buf_release(&surv);
    buf_release(&per);
    buf_release(&dep);
    return result;
}

/* destinations((queries, steps, objects, targets, locations), per, group_query, group_act, src,
 *              index, values, destination, step)
 *   Adds per[g, j] times the destination row of (activity group_act[g], object j, place
 *   src[group_query[g], j]) (row index[(a * objects + j) * locations + place] of values) to
 *   destination[group_query[g], step, j], group by group in order (a query's groups are
 *   consecutive). */
static PyObject *destinations(PyObject *self, PyObject *args) {
    PyObject *o_per, *o_gq, *o_ga, *o_src, *o_index, *o_values, *o_dest;
    Py_ssize_t nq, nsteps, nj, width, nl, step;
    if (!PyArg_ParseTuple(args, "(nnnnn)OOOOOOOn", &nq, &nsteps, &nj, &width, &nl, &o_per, &o_gq, &o_ga, &o_src,
                          &o_index, &o_values, &o_dest, &step))
        return NULL;
    Buf per = {0}, gq = {0}, ga = {0}, src = {0}, index = {0}, values = {0}, dest = {0};
    PyObject *result = NULL;
    if (nq < 0 || nsteps < 1 || nj < 0 || width < 1 || nl < 1 || step < 0 || step >= nsteps) {
        bad("a destination shape or the step");
        goto done;
    }
    Py_ssize_t n_src = times(nq, nj), n_dest = times(times(times(nq, nsteps), nj), width), per_act = times(nj, nl);
    if (n_src < 0 || n_dest < 0 || per_act < 0 || buf_get(o_gq, &gq, I64, 0, "group_query") < 0 ||
        buf_sized(o_ga, &ga, I64, 0, gq.n, "group_act") < 0 || buf_sized(o_per, &per, F64, 0, times(gq.n, nj), "per") < 0 ||
        buf_sized(o_src, &src, I64, 0, n_src, "src") < 0 || buf_get(o_index, &index, I64, 0, "index") < 0 ||
        buf_get(o_values, &values, F64, 0, "values") < 0 || buf_sized(o_dest, &dest, F64, 1, n_dest, "destination") < 0)
        goto done;
    Py_ssize_t nacts = per_act ? index.n / per_act : 0; /* activities the index covers */
    Py_ssize_t nrows = values.n / width;
    if (values.n != nrows * width) {
        bad("the destination rows' size");
        goto done;
    }
    const int64_t *group_query = I64P(gq), *group_act = I64P(ga), *place = I64P(src), *row_of = I64P(index);
    const double *sums = F64P(per), *rows = F64P(values);
    double *out = F64P(dest);
    for (Py_ssize_t g = 0; g < gq.n; g++) {
        int64_t q = group_query[g], a = group_act[g];
        if (q < 0 || q >= nq || a < 0 || a >= nacts || (g && q < group_query[g - 1])) {
            bad("a group's query or activity");
            goto done;
        }
        for (Py_ssize_t j = 0; j < nj; j++) {
            int64_t x = place[q * nj + j];
            if (x < 0 || x >= nl) {
                bad("a place");
                goto done;
            }
            int64_t r = row_of[(a * nj + j) * nl + x];
            if (r < 0 || r >= nrows) {
                bad("a destination row (not filled in)");
                goto done;
            }
            double v = sums[g * nj + j], *to = out + ((q * nsteps + step) * nj + j) * width;
            const double *row = rows + r * width;
            for (Py_ssize_t x2 = 0; x2 < width; x2++) to[x2] += v * row[x2];
        }
    }
    result = Py_NewRef(Py_None);
done:
    buf_release(&per);
    buf_release(&gq);
    buf_release(&ga);
    buf_release(&src);
    buf_release(&index);
    buf_release(&values);
    buf_release(&dest);
    return result;
}

static PyMethodDef methods[] = {
    {"level", level, METH_VARARGS, "One level of the paths: hazards, departures, group sums and survival."},
    {"destinations", destinations, METH_VARARGS, "Add each group's departures times its destinations."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_propagate", NULL, -1, methods};

PyMODINIT_FUNC PyInit__propagate(void) { return PyModule_Create(&module); }
