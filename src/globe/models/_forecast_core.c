/* The forecaster's hot loops in C: globe.models.forecast.Forecaster.forecast_many, first_locations
 * and ActivityPaths' forward pass.
 *
 * forecast_many spends its time on arrays of (path node x object): the hazard read for each,
 * what leaves and what survives, sums per query and per (query, activity left), then those sums
 * times each object's destinations. level() and destinations() do the same arithmetic in the
 * same order (numpy's bincount adds its weights one by one in input order, and so do they), so
 * every number has the same bits as the numpy code, which stays the reference and the fallback
 * where this module is not compiled (tested side by side on HOMER+ queries). first_locations()
 * sums over steps as np.cumsum does and picks as np.argmax does. Optional.
 *
 * Paths: the forward pass over activity paths (ActivityPaths._beams, see
 * globe/models/forecast.py). Each step extends, prunes, cuts and renormalises the paths of every
 * query as the numpy code does, in the same order. ROUTINE: a state is the last `order` run
 * labels, when the current run began and the step (the same merging as the Python dynamics'
 * keys), numbered here; its next-step distribution is mixed here, exactly as
 * _RoutineDynamics._compute mixes it, from two parts asked from Python once each and remembered
 * (the stay probability of (activity, duration, step), the next run's distribution of (run
 * labels, step)). OPAQUE (any other model): the states are ActivityPaths' own, each new one's
 * distribution and children asked from it, so they are numbered as in Python. Either way the
 * next-step items of a state and the states they lead to are remembered next to each other.
 *
 * Floating point: products and sums are never fused (setup.py builds with -ffp-contract=off;
 * checked at import). Every index read from an argument is checked before it is used: a bad
 * input raises ValueError, it is never read out of bounds.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "_c_common.h"

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF /* GCC ignores it: setup.py passes -ffp-contract=off */
#endif

/* -- buffers ------------------------------------------------------------------------------------- */

typedef enum { F64, I64, BOOL } Kind;

typedef struct {
    Py_buffer view;
    Py_ssize_t n; /* items */
    int held;
} Buf;

static const char *kind_name(Kind kind) { return kind == F64 ? "float64" : kind == I64 ? "int64" : "bool"; }

/* Borrow `obj`'s memory as a C-contiguous array of `kind` (writable if asked). */
static int buf_get(PyObject *obj, Buf *b, Kind kind, int writable, const char *what) {
    int flags = PyBUF_C_CONTIGUOUS | PyBUF_FORMAT | (writable ? PyBUF_WRITABLE : 0);
    if (PyObject_GetBuffer(obj, &b->view, flags) < 0) {
        PyErr_Format(PyExc_ValueError, "forecast core: %s must be a contiguous %s%s array", what,
                     writable ? "writable " : "", kind_name(kind));
        return -1;
    }
    b->held = 1;
    const char *f = b->view.format ? b->view.format : "B";
    if (*f == '@' || *f == '=' || *f == '<') f++;
    int ok = kind == F64   ? (f[0] == 'd' && f[1] == 0 && b->view.itemsize == 8)
             : kind == I64 ? ((f[0] == 'l' || f[0] == 'q') && f[1] == 0 && b->view.itemsize == 8)
                           : (f[0] == '?' && f[1] == 0 && b->view.itemsize == 1);
    if (!ok) {
        PyErr_Format(PyExc_ValueError, "forecast core: %s must be %s, not '%s'", what, kind_name(kind), f);
        return -1;
    }
    b->n = b->view.len / b->view.itemsize;
    return 0;
}

/* The same, and it must hold exactly `n` items. */
static int buf_sized(PyObject *obj, Buf *b, Kind kind, int writable, Py_ssize_t n, const char *what) {
    if (buf_get(obj, b, kind, writable, what) < 0) return -1;
    if (b->n != n) {
        PyErr_Format(PyExc_ValueError, "forecast core: %s holds %zd items, expected %zd", what, b->n, n);
        return -1;
    }
    return 0;
}

static void buf_release(Buf *b) {
    if (b->held) PyBuffer_Release(&b->view);
    b->held = 0;
}

#define F64P(b) ((double *)(b).view.buf)
#define I64P(b) ((const int64_t *)(b).view.buf)
#define BOOLP(b) ((const char *)(b).view.buf)

static PyObject *as_bytes(const void *p, Py_ssize_t n, size_t size) {
    return PyByteArray_FromStringAndSize(n ? (const char *)p : "", n * (Py_ssize_t)size);
}

static int bad(const char *what) {
    PyErr_Format(PyExc_ValueError, "forecast core: %s out of range", what);
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

/* The hazards of every object for node n (owner q, parent activity a) into h[0..nj):
 * Forecaster._propagate's lookups, switch mix and fallback for objects never seen at their
 * place, in its order (check_model has checked every cell). */
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
        PyErr_Format(PyExc_ValueError, "forecast core: %s must be a tuple of %d arrays", what, count);
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
 *   objects) and to departure (queries x steps x objects) at `step`, node by node, as
 *   np.bincount adds. */
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
 *   destination[group_query[g], step, j], group by group in order: a query's groups are
 *   consecutive, so each sum runs in the numpy code's order. */
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

/* first_locations((queries, steps, objects, targets), horizons, destination, target_table)
 *   -> (location bytearray int64, probability bytearray float64), each (queries x horizons x
 *   objects): per object the most likely first new place within the first s + 1 steps (the
 *   running sum over steps, as np.cumsum adds; its first largest target, as np.argmax picks,
 *   NaN first) and its probability. */
static PyObject *first_locations(PyObject *self, PyObject *args) {
    PyObject *o_dest, *o_targets;
    Py_ssize_t nq, nsteps, nj, width, horizons;
    if (!PyArg_ParseTuple(args, "(nnnn)nOO", &nq, &nsteps, &nj, &width, &horizons, &o_dest, &o_targets)) return NULL;
    if (nq < 0 || nsteps < 0 || nj < 0 || width < 1 || horizons < 0) return PyErr_Format(PyExc_ValueError, "forecast core: bad shape");
    if (horizons > nsteps) horizons = nsteps;
    Buf dest = {0}, targets = {0};
    double *joint = NULL, *prob = NULL;
    int64_t *where = NULL;
    PyObject *result = NULL;
    Py_ssize_t n = times(times(nq, horizons), nj), n_dest = times(times(times(nq, nsteps), nj), width);
    if (n < 0 || n_dest < 0 || buf_sized(o_dest, &dest, F64, 0, n_dest, "destination") < 0 ||
        buf_sized(o_targets, &targets, I64, 0, times(nj, width), "targets") < 0)
        goto done;
    joint = PyMem_Malloc((size_t)(width) * sizeof(double));
    prob = PyMem_Malloc((size_t)(n ? n : 1) * sizeof(double));
    where = PyMem_Malloc((size_t)(n ? n : 1) * sizeof(int64_t));
    if (!joint || !prob || !where) {
        PyErr_NoMemory();
        goto done;
    }
    const double *d = F64P(dest);
    const int64_t *t = I64P(targets);
    for (Py_ssize_t q = 0; q < nq; q++)
        for (Py_ssize_t j = 0; j < nj; j++)
            for (Py_ssize_t k = 0; k < horizons; k++) {
                const double *row = d + ((q * nsteps + k) * nj + j) * width;
                Py_ssize_t best = 0;
                for (Py_ssize_t x = 0; x < width; x++) joint[x] = k ? joint[x] + row[x] : row[x];
                for (Py_ssize_t x = 0; x < width; x++) {
                    if (joint[x] != joint[x]) { /* NaN: numpy's argmax takes the first */
                        best = x;
                        break;
                    }
                    if (joint[x] > joint[best]) best = x;
                }
                Py_ssize_t o = (q * horizons + k) * nj + j;
                where[o] = t[j * width + best];
                prob[o] = joint[best];
            }
    result = Py_BuildValue("(NN)", as_bytes(where, n, sizeof(int64_t)), as_bytes(prob, n, sizeof(double)));
done:
    buf_release(&dest);
    buf_release(&targets);
    PyMem_Free(joint);
    PyMem_Free(prob);
    PyMem_Free(where);
    return result;
}

/* -- Paths: the routine model's forward pass ------------------------------------------------------ */

/* A hash map from keys of `width` integers to one integer (open addressing, linear probing). */
typedef struct {
    Py_ssize_t width, cap, n;
    int64_t *keys, *values;
    char *used;
} Table;

static uint64_t hash_key(const int64_t *k, Py_ssize_t w) {
    uint64_t h = 0x9E3779B97F4A7C15ULL;
    for (Py_ssize_t i = 0; i < w; i++) h = mix64(h ^ ((uint64_t)k[i] * 0xBF58476D1CE4E5B9ULL + (uint64_t)i));
    return h;
}

static int table_get(const Table *t, const int64_t *k, int64_t *out) {
    if (t->cap == 0) return 0;
    size_t mask = (size_t)t->cap - 1, i = (size_t)hash_key(k, t->width) & mask;
    while (t->used[i]) {
        if (memcmp(t->keys + i * t->width, k, (size_t)t->width * sizeof(int64_t)) == 0) {
            *out = t->values[i];
            return 1;
        }
        i = (i + 1) & mask;
    }
    return 0;
}

static void table_place(Table *t, const int64_t *k, int64_t v) {
    size_t mask = (size_t)t->cap - 1, i = (size_t)hash_key(k, t->width) & mask;
    while (t->used[i] && memcmp(t->keys + i * t->width, k, (size_t)t->width * sizeof(int64_t)) != 0) i = (i + 1) & mask;
    if (!t->used[i]) t->n++;
    t->used[i] = 1;
    memcpy(t->keys + i * t->width, k, (size_t)t->width * sizeof(int64_t));
    t->values[i] = v;
}

/* Set k -> v (a new key or a new value). */
static int table_put(Table *t, const int64_t *k, int64_t v) {
    if (2 * (t->n + 1) > t->cap) {
        Table bigger = {t->width, t->cap ? 2 * t->cap : 256, 0, NULL, NULL, NULL};
        bigger.keys = PyMem_Malloc((size_t)bigger.cap * (size_t)t->width * sizeof(int64_t));
        bigger.values = PyMem_Malloc((size_t)bigger.cap * sizeof(int64_t));
        bigger.used = PyMem_Calloc((size_t)bigger.cap, 1);
        if (!bigger.keys || !bigger.values || !bigger.used) {
            PyMem_Free(bigger.keys);
            PyMem_Free(bigger.values);
            PyMem_Free(bigger.used);
            PyErr_NoMemory();
            return -1;
        }
        for (Py_ssize_t i = 0; i < t->cap; i++)
            if (t->used[i]) table_place(&bigger, t->keys + i * t->width, t->values[i]);
        PyMem_Free(t->keys);
        PyMem_Free(t->values);
        PyMem_Free(t->used);
        *t = bigger;
    }
    table_place(t, k, v);
    return 0;
}

static void table_free(Table *t) {
    PyMem_Free(t->keys);
    PyMem_Free(t->values);
    PyMem_Free(t->used);
    t->keys = t->values = NULL;
    t->used = NULL;
    t->cap = t->n = 0;
}

#define MAX_ORDER 64
#define DAY (-2)  /* the run index's day-start token in a state's labels */
#define NONE (-1) /* no label (a key shorter than the order) */

typedef struct { /* activities and probabilities, list after list */
    int32_t *act;
    double *p;
    Py_ssize_t n, cap_act, cap_p;
} Items;

static int items_push(Items *t, int32_t a, double p) {
    if (reserve((void **)&t->act, &t->cap_act, t->n + 1, sizeof(int32_t)) < 0 ||
        reserve((void **)&t->p, &t->cap_p, t->n + 1, sizeof(double)) < 0)
        return -1;
    t->act[t->n] = a;
    t->p[t->n++] = p;
    return 0;
}

enum { ROUTINE = 0, OPAQUE = 1 };

typedef struct {
    PyObject_HEAD
    int kind;            /* ROUTINE: states numbered here; OPAQUE: the caller's (ActivityPaths') numbers */
    Py_ssize_t order;
    int step_free;       /* the next run's distribution does not depend on the step */
    PyObject *names;     /* dict: activity -> local id (ActivityPaths.names) */
    PyObject *name_list; /* list: local id -> activity */
    PyObject *day;       /* the day-start token */
    /* states: `order` labels (oldest first), when the current run began (-1: no run yet), step */
    Py_ssize_t n, cap_tok, cap_start, cap_step, cap_first, cap_count, cap_best;
    int32_t *tok;
    int64_t *start, *step;
    Py_ssize_t *first; /* each state's next-step items in `ext` ... */
    int32_t *count;    /* ... how many (-1: not computed yet) ... */
    int32_t *best;     /* ... and which of them is the most probable (-1: none) */
    Items ext;
    int64_t *ext_child; /* the state each item leads to (-1: not asked yet) */
    Py_ssize_t cap_child;
    Table states;   /* (labels, start, step) -> state */
    Table stays;    /* (activity, duration, step) -> index in stay_values */
    double *stay_values;
    Py_ssize_t nstay, cap_stay;
    Table runs; /* (labels, step or -1) -> index in run_first/run_len/run_z */
    Items run_items;
    Py_ssize_t *run_first, *run_len, nruns, cap_rf, cap_rl, cap_rz;
    double *run_z;
    int32_t *rank; /* rank of each local id's name in sorted order */
    Py_ssize_t nrank;
} Paths;

static int paths_grow(Paths *s) {
    Py_ssize_t need = s->n + 1;
    if (reserve((void **)&s->tok, &s->cap_tok, need * s->order, sizeof(int32_t)) < 0 ||
        reserve((void **)&s->start, &s->cap_start, need, sizeof(int64_t)) < 0 ||
        reserve((void **)&s->step, &s->cap_step, need, sizeof(int64_t)) < 0 ||
        reserve((void **)&s->first, &s->cap_first, need, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&s->count, &s->cap_count, need, sizeof(int32_t)) < 0 ||
        reserve((void **)&s->best, &s->cap_best, need, sizeof(int32_t)) < 0)
        return -1;
    return 0;
}

/* The state of (labels, start, step), numbered on first sight. */
static Py_ssize_t state_of(Paths *s, const int32_t *tok, int64_t start, int64_t step) {
    int64_t key[MAX_ORDER + 2], found;
    for (Py_ssize_t i = 0; i < s->order; i++) key[i] = tok[i];
    key[s->order] = start;
    key[s->order + 1] = step;
    if (table_get(&s->states, key, &found)) return (Py_ssize_t)found;
    if (paths_grow(s) < 0 || table_put(&s->states, key, s->n) < 0) return -1;
    Py_ssize_t id = s->n++;
    for (Py_ssize_t i = 0; i < s->order; i++) s->tok[id * s->order + i] = (int32_t)key[i]; /* tok may point into the old array */
    s->start[id] = start;
    s->step[id] = step;
    s->first[id] = 0;
    s->count[id] = -1;
    s->best[id] = -1;
    return id;
}

/* Make room for the caller's state `id` (OPAQUE). */
static int cover(Paths *s, Py_ssize_t id) {
    if (id < 0 || id >= PY_SSIZE_T_MAX / 16) return bad("a state");
    if (id < s->n) return 0;
    Py_ssize_t need = id + 1;
    if (reserve((void **)&s->first, &s->cap_first, need, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&s->count, &s->cap_count, need, sizeof(int32_t)) < 0 ||
        reserve((void **)&s->best, &s->cap_best, need, sizeof(int32_t)) < 0)
        return -1;
    for (Py_ssize_t i = s->n; i < need; i++) {
        s->first[i] = 0;
        s->count[i] = -1;
        s->best[i] = -1;
    }
    s->n = need;
    return 0;
}

static PyObject *name_of(Paths *s, int32_t id);

/* The state after `id` and activity `act`, the item at `item` of its next-step items (remembered
 * there). ROUTINE: the same labels while the run goes on, else `act` appended and the run
 * starting now (_RoutineDynamics.child_key); OPAQUE: asked from `child_fn` (ActivityPaths._child). */
static Py_ssize_t child_of(Paths *s, PyObject *child_fn, Py_ssize_t id, int32_t act, Py_ssize_t item) {
    if (s->ext_child[item] >= 0) return (Py_ssize_t)s->ext_child[item];
    if (s->kind == OPAQUE) {
        PyObject *r = PyObject_CallFunction(child_fn, "ni", id, (int)act);
        Py_ssize_t child = r ? PyLong_AsSsize_t(r) : -1;
        Py_XDECREF(r);
        if ((child == -1 && PyErr_Occurred()) || cover(s, child) < 0) return -1;
        s->ext_child[item] = child;
        return child;
    }
    int32_t tok[MAX_ORDER];
    const int32_t *parent = s->tok + id * s->order;
    int64_t start = s->start[id], step = s->step[id];
    Py_ssize_t child;
    if (start >= 0 && parent[s->order - 1] == act) {
        child = state_of(s, parent, start, step + 1);
    } else {
        for (Py_ssize_t i = 0; i + 1 < s->order; i++) tok[i] = parent[i + 1];
        tok[s->order - 1] = act;
        child = state_of(s, tok, step, step + 1);
    }
    if (child >= 0) s->ext_child[item] = child;
    return child;
}

/* The local id of `name`, numbered on first sight (ActivityPaths.local). */
static int32_t local_id(Paths *s, PyObject *name) {
    PyObject *id = PyDict_GetItemWithError(s->names, name);
    if (id != NULL) {
        long v = PyLong_AsLong(id);
        if (v == -1 && PyErr_Occurred()) return -1;
        if (v < 0 || v >= PyList_GET_SIZE(s->name_list) || v > INT32_MAX - 1) {
            PyErr_SetString(PyExc_ValueError, "forecast core: an activity's local id is out of range");
            return -1;
        }
        return (int32_t)v;
    }
    if (PyErr_Occurred()) return -1;
    Py_ssize_t n = PyList_GET_SIZE(s->name_list);
    if (n >= INT32_MAX - 1) return bad("the number of activities");
    PyObject *number = PyLong_FromSsize_t(n);
    if (number == NULL) return -1;
    int err = PyDict_SetItem(s->names, name, number);
    Py_DECREF(number);
    if (err < 0 || PyList_Append(s->name_list, name) < 0) return -1;
    return (int32_t)n;
}

static PyObject *name_of(Paths *s, int32_t id) {
    if (id == DAY) return s->day;
    if (id < 0 || id >= PyList_GET_SIZE(s->name_list)) {
        bad("an activity id");
        return NULL;
    }
    return PyList_GET_ITEM(s->name_list, id);
}

/* Rank of every local id's name in sorted order (paths tie-break lexicographically). */
static int ranks(Paths *s) {
    Py_ssize_t n = PyList_GET_SIZE(s->name_list);
    if (n == s->nrank) return 0;
    int32_t *order = PyMem_Malloc((size_t)(n ? n : 1) * sizeof(int32_t));
    int32_t *rank = PyMem_Realloc(s->rank, (size_t)(n ? n : 1) * sizeof(int32_t));
    if (order == NULL || rank == NULL) {
        PyMem_Free(order);
        if (rank) s->rank = rank;
        PyErr_NoMemory();
        return -1;
    }
    s->rank = rank;
    for (Py_ssize_t i = 0; i < n; i++) { /* insertion sort: a household has few activities */
        Py_ssize_t j = i;
        while (j > 0) {
            int lt = PyObject_RichCompareBool(PyList_GET_ITEM(s->name_list, i), PyList_GET_ITEM(s->name_list, order[j - 1]), Py_LT);
            if (lt < 0) {
                PyMem_Free(order);
                s->nrank = -1;
                return -1;
            }
            if (!lt) break;
            order[j] = order[j - 1];
            j--;
        }
        order[j] = (int32_t)i;
    }
    for (Py_ssize_t i = 0; i < n; i++) s->rank[order[i]] = (int32_t)i;
    PyMem_Free(order);
    s->nrank = n;
    return 0;
}

/* Append a distribution (a dict activity -> probability) to `t` in its order, its entries with
 * probability > 0 only when `positive`; the activities are numbered on first sight. */
static int items_from_dict(Paths *s, Items *t, PyObject *dist, int positive) {
    if (!PyDict_Check(dist)) {
        PyErr_SetString(PyExc_TypeError, "forecast core: a distribution must be a dict");
        return -1;
    }
    PyObject *name, *value;
    Py_ssize_t pos = 0;
    while (PyDict_Next(dist, &pos, &name, &value)) {
        double p = PyFloat_AsDouble(value);
        if (p == -1.0 && PyErr_Occurred()) return -1;
        if (positive && !(p > 0)) continue;
        int32_t a = local_id(s, name);
        if (a < 0 || items_push(t, a, p) < 0) return -1;
    }
    return 0;
}

static int stay_of(Paths *s, PyObject *stay_fn, int32_t act, int64_t duration, int64_t step, double *out) {
    int64_t key[3] = {act, duration, step}, found;
    if (table_get(&s->stays, key, &found)) {
        *out = s->stay_values[found];
        return 0;
    }
    PyObject *name = name_of(s, act);
    if (name == NULL) return -1;
    PyObject *r = PyObject_CallFunction(stay_fn, "OLL", name, (long long)duration, (long long)step);
    if (r == NULL) return -1;
    double v = PyFloat_AsDouble(r);
    Py_DECREF(r);
    if (v == -1.0 && PyErr_Occurred()) return -1;
    if (reserve((void **)&s->stay_values, &s->cap_stay, s->nstay + 1, sizeof(double)) < 0 ||
        table_put(&s->stays, key, s->nstay) < 0)
        return -1;
    s->stay_values[s->nstay++] = v;
    *out = v;
    return 0;
}

/* The next run's distribution after the labels of state `id` at its step (entry of run_*). */
static Py_ssize_t next_of(Paths *s, PyObject *next_fn, Py_ssize_t id) {
    int64_t key[MAX_ORDER + 1], found;
    const int32_t *tok = s->tok + id * s->order;
    for (Py_ssize_t i = 0; i < s->order; i++) key[i] = tok[i];
    key[s->order] = s->step_free ? -1 : s->step[id];
    if (table_get(&s->runs, key, &found)) return (Py_ssize_t)found;
    Py_ssize_t n = 0;
    while (n < s->order && tok[n] == NONE) n++;
    PyObject *labels = PyTuple_New(s->order - n);
    if (labels == NULL) return -1;
    for (Py_ssize_t i = n; i < s->order; i++) {
        PyObject *name = name_of(s, tok[i]);
        if (name == NULL) {
            Py_DECREF(labels);
            return -1;
        }
        PyTuple_SET_ITEM(labels, i - n, Py_NewRef(name));
    }
    PyObject *current = name_of(s, tok[s->order - 1]);
    PyObject *r = current ? PyObject_CallFunction(next_fn, "OOL", labels, current, (long long)s->step[id]) : NULL;
    Py_DECREF(labels);
    if (r == NULL) return -1;
    double z;
    PyObject *dist;
    if (!PyArg_ParseTuple(r, "Od", &dist, &z)) {
        Py_DECREF(r);
        return -1;
    }
    Py_ssize_t first = s->run_items.n;
    int err = items_from_dict(s, &s->run_items, dist, 1);
    Py_DECREF(r);
    if (err < 0 || reserve((void **)&s->run_first, &s->cap_rf, s->nruns + 1, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&s->run_len, &s->cap_rl, s->nruns + 1, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&s->run_z, &s->cap_rz, s->nruns + 1, sizeof(double)) < 0 || table_put(&s->runs, key, s->nruns) < 0)
        return -1;
    s->run_first[s->nruns] = first;
    s->run_len[s->nruns] = s->run_items.n - first;
    s->run_z[s->nruns] = z;
    return s->nruns++;
}

/* The next-step distribution of the caller's state `id` (OPAQUE): distribution_fn(id) -> (dict,
 * the last activity or None); a model with nothing to say keeps the activity. */
static int opaque_items(Paths *s, PyObject *distribution_fn, Py_ssize_t id) {
    PyObject *r = PyObject_CallFunction(distribution_fn, "n", id), *dist, *last;
    if (r == NULL) return -1;
    int err = -1;
    if (!PyArg_ParseTuple(r, "O!O", &PyDict_Type, &dist, &last)) goto done;
    if (PyDict_GET_SIZE(dist) == 0 && last != Py_None) {
        int32_t a = local_id(s, last);
        err = a < 0 ? -1 : items_push(&s->ext, a, 1.0);
    } else {
        err = items_from_dict(s, &s->ext, dist, 1);
    }
done:
    Py_DECREF(r);
    return err;
}

/* Fill state `id`'s next-step items: the activities with probability > 0 in the model's order
 * and the most probable (ties: the larger name), as ActivityPaths._ensure; for ROUTINE over the
 * distribution _RoutineDynamics._compute mixes. */
static int ensure(Paths *s, PyObject *stay_fn, PyObject *next_fn, PyObject *first_fn, Py_ssize_t id) {
    if (s->count[id] >= 0) return 0;
    Py_ssize_t first = s->ext.n;
    if (s->kind == OPAQUE) {
        if (opaque_items(s, stay_fn, id) < 0) return -1;
    } else if (s->start[id] < 0) { /* no run yet: the model's first-step distribution */
        PyObject *dist = PyObject_CallFunction(first_fn, "L", (long long)s->step[id]);
        if (dist == NULL) return -1;
        int err = items_from_dict(s, &s->ext, dist, 1);
        Py_DECREF(dist);
        if (err < 0) return -1;
    } else {
        int32_t current = s->tok[id * s->order + s->order - 1];
        double stay;
        if (stay_of(s, stay_fn, current, s->step[id] - s->start[id], s->step[id], &stay) < 0) return -1;
        Py_ssize_t r = next_of(s, next_fn, id);
        if (r < 0) return -1;
        double z = s->run_z[r];
        int found = 0;
        if (z > 0)
            for (Py_ssize_t i = 0; i < s->run_len[r]; i++) {
                int32_t b = s->run_items.act[s->run_first[r] + i];
                double p = s->run_items.p[s->run_first[r] + i];
                if (items_push(&s->ext, b, (1.0 - stay) * p / z) < 0) return -1;
                if (b == current) {
                    s->ext.p[s->ext.n - 1] = stay;
                    found = 1;
                }
            }
        if (!found && items_push(&s->ext, current, z > 0 ? stay : 1.0) < 0) return -1;
    } /* (never empty with a run under way: the Python fallback to the last activity is not needed) */
    /* keep the positive ones, in order; the most probable: the larger name among ties */
    double top = 0.0;
    Py_ssize_t kept = first;
    for (Py_ssize_t i = first; i < s->ext.n; i++)
        if (s->ext.p[i] > top) top = s->ext.p[i];
    if (ranks(s) < 0) return -1;
    int32_t best = -1, best_rank = -1;
    for (Py_ssize_t i = first; i < s->ext.n; i++) {
        if (!(s->ext.p[i] > 0)) continue;
        s->ext.act[kept] = s->ext.act[i];
        s->ext.p[kept] = s->ext.p[i];
        int32_t a = s->ext.act[kept];
        if (a < 0 || a >= s->nrank) return bad("an activity id");
        if (s->ext.p[kept] == top && s->rank[a] > best_rank) {
            best = (int32_t)(kept - first);
            best_rank = s->rank[a];
        }
        kept++;
    }
    s->ext.n = kept;
    if (reserve((void **)&s->ext_child, &s->cap_child, kept, sizeof(int64_t)) < 0) return -1;
    for (Py_ssize_t i = first; i < kept; i++) s->ext_child[i] = -1;
    s->first[id] = first;
    s->count[id] = (int32_t)(kept - first);
    s->best[id] = top > 0 ? best : -1;
    return 0;
}

/* -- the beam step -- */

typedef struct {           /* the extensions of one step, in the forward pass's order */
    Py_ssize_t *entry;     /* the path (entry of the level before) extended */
    int32_t *act;          /* by this activity */
    double *p;             /* with this probability */
    const int64_t *lex;    /* the extended paths' lexicographic ranks */
    const int32_t *rank;   /* the activities' names' ranks */
} Candidates;

static int most_probable_first(const void *ctx, Py_ssize_t a, Py_ssize_t b) {
    const Candidates *c = ctx;
    if (c->p[a] != c->p[b]) return c->p[a] > c->p[b];
    if (c->lex[c->entry[a]] != c->lex[c->entry[b]]) return c->lex[c->entry[a]] < c->lex[c->entry[b]];
    return c->rank[c->act[a]] < c->rank[c->act[b]];
}

typedef struct {
    const Candidates *cand;
    const Py_ssize_t *kept;
} Kept;

/* kept[a] before kept[b] in path order: the extended path's, then the activity's name. */
static int lexicographic(const void *ctx, Py_ssize_t a, Py_ssize_t b) {
    const Kept *k = ctx;
    const Candidates *c = k->cand;
    Py_ssize_t x = k->kept[a], y = k->kept[b];
    if (c->lex[c->entry[x]] != c->lex[c->entry[y]]) return c->lex[c->entry[x]] < c->lex[c->entry[y]];
    return c->rank[c->act[x]] < c->rank[c->act[y]];
}

typedef struct { /* the kept paths of a level */
    Py_ssize_t n, cap_q, cap_p, cap_a, cap_e, cap_l, cap_s;
    int64_t *query, *act, *parent, *lex, *sid;
    double *p;
} Level;

static int level_push(Level *l, int64_t q, double p, int64_t a, int64_t parent, int64_t sid) {
    Py_ssize_t need = l->n + 1;
    if (reserve((void **)&l->query, &l->cap_q, need, sizeof(int64_t)) < 0 || reserve((void **)&l->p, &l->cap_p, need, sizeof(double)) < 0 ||
        reserve((void **)&l->act, &l->cap_a, need, sizeof(int64_t)) < 0 ||
        reserve((void **)&l->parent, &l->cap_e, need, sizeof(int64_t)) < 0 ||
        reserve((void **)&l->lex, &l->cap_l, need, sizeof(int64_t)) < 0 || reserve((void **)&l->sid, &l->cap_s, need, sizeof(int64_t)) < 0)
        return -1;
    l->query[l->n] = q;
    l->p[l->n] = p;
    l->act[l->n] = a;
    l->parent[l->n] = parent;
    l->lex[l->n] = 0;
    l->sid[l->n++] = sid;
    return 0;
}

static void level_free(Level *l) {
    PyMem_Free(l->query);
    PyMem_Free(l->p);
    PyMem_Free(l->act);
    PyMem_Free(l->parent);
    PyMem_Free(l->lex);
    PyMem_Free(l->sid);
    memset(l, 0, sizeof(Level));
}

static PyObject *level_tuple(const Level *l) {
    return Py_BuildValue("(NNNNNN)", as_bytes(l->query, l->n, 8), as_bytes(l->p, l->n, 8), as_bytes(l->act, l->n, 8),
                         as_bytes(l->parent, l->n, 8), as_bytes(l->lex, l->n, 8), as_bytes(l->sid, l->n, 8));
}

typedef struct { /* scratch of one step */
    Py_ssize_t n, cap_e, cap_a, cap_p, cap_i, cap_t, cap_k, cap_x;
    Py_ssize_t *entry, *idx, *tmp, *kept, *item;
    int32_t *act;
    double *p;
} Scratch;

static int scratch_reserve(Scratch *c, Py_ssize_t need) {
    if (reserve((void **)&c->entry, &c->cap_e, need, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&c->act, &c->cap_a, need, sizeof(int32_t)) < 0 || reserve((void **)&c->p, &c->cap_p, need, sizeof(double)) < 0 ||
        reserve((void **)&c->idx, &c->cap_i, need, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&c->tmp, &c->cap_t, need, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&c->kept, &c->cap_k, need, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&c->item, &c->cap_x, need, sizeof(Py_ssize_t)) < 0)
        return -1;
    return 0;
}

static void scratch_free(Scratch *c) {
    PyMem_Free(c->entry);
    PyMem_Free(c->act);
    PyMem_Free(c->p);
    PyMem_Free(c->idx);
    PyMem_Free(c->tmp);
    PyMem_Free(c->kept);
    PyMem_Free(c->item);
    memset(c, 0, sizeof(Scratch));
}

typedef struct {
    PyObject *stay, *next, *first;
    double minp;
    Py_ssize_t most;
} Step;

static int ascending(const void *a, const void *b) {
    Py_ssize_t x = *(const Py_ssize_t *)a, y = *(const Py_ssize_t *)b;
    return (x > y) - (x < y);
}

/* Fill the next-step items of every state of `from` not filled yet, in the order of their numbers
 * (the order ActivityPaths._ensure fills them: new names are numbered in the same order). */
static int ensure_all(Paths *s, const Step *st, const Level *from, Scratch *c) {
    Py_ssize_t n = 0;
    if (scratch_reserve(c, from->n) < 0) return -1;
    for (Py_ssize_t e = 0; e < from->n; e++)
        if (s->count[from->sid[e]] < 0) c->idx[n++] = (Py_ssize_t)from->sid[e];
    qsort(c->idx, (size_t)n, sizeof(Py_ssize_t), ascending);
    for (Py_ssize_t i = 0; i < n; i++)
        if (ensure(s, st->stay, st->next, st->first, c->idx[i]) < 0) return -1;
    return ranks(s);
}

/* One query's extensions c->idx[lo..hi): kept as ActivityPaths._beams keeps them (those above the
 * floor, else the most probable; the `most` most probable, then lexicographically by path),
 * renormalised, numbered lexicographically, appended to `to`. */
static int keep_query(Paths *s, const Step *st, const Level *from, Scratch *c, Py_ssize_t lo, Py_ssize_t hi, Level *to) {
    Candidates cand = {c->entry, c->act, c->p, from->lex, s->rank};
    Py_ssize_t nk = 0, top = lo;
    for (Py_ssize_t i = lo; i < hi; i++) {
        if (c->p[i] >= st->minp) c->kept[nk++] = i;
        if (c->p[i] > c->p[top]) top = i;
    }
    if (nk == 0) c->kept[nk++] = top; /* nothing above the floor: the most probable (first of ties) */
    if (nk > st->most) {
        sort_indices(c->kept, c->tmp, nk, most_probable_first, &cand);
        nk = st->most;
    }
    double z = 0.0;
    for (Py_ssize_t k = 0; k < nk; k++) z += c->p[c->kept[k]];
    Py_ssize_t base = to->n;
    for (Py_ssize_t k = 0; k < nk; k++) {
        Py_ssize_t i = c->kept[k], e = c->entry[i];
        Py_ssize_t child = child_of(s, st->next, (Py_ssize_t)from->sid[e], c->act[i], c->item[i]);
        if (child < 0 || level_push(to, from->query[e], c->p[i] / z, c->act[i], e, child) < 0) return -1;
    }
    Kept order = {&cand, c->kept};
    for (Py_ssize_t k = 0; k < nk; k++) c->idx[k] = k;
    sort_indices(c->idx, c->tmp, nk, lexicographic, &order);
    for (Py_ssize_t r = 0; r < nk; r++) to->lex[base + c->idx[r]] = r; /* each kept path's rank in path order */
    return 0;
}

/* One step of the forward pass from the paths of `from` to `to`. */
static int step_once(Paths *s, const Step *st, const Level *from, Scratch *c, Level *to) {
    if (ensure_all(s, st, from, c) < 0) return -1;
    c->n = 0;
    for (Py_ssize_t e = 0; e < from->n; e++) { /* path by path, in the model's order */
        Py_ssize_t id = (Py_ssize_t)from->sid[e];
        Py_ssize_t first = s->first[id], count = s->count[id], best = s->best[id];
        if (scratch_reserve(c, c->n + count) < 0) return -1;
        for (Py_ssize_t k = 0; k < count; k++) {
            double pq = from->p[e] * s->ext.p[first + k];
            if (pq >= st->minp || k == best) {
                c->entry[c->n] = e;
                c->act[c->n] = s->ext.act[first + k];
                c->item[c->n] = first + k;
                c->p[c->n++] = pq;
            }
        }
    }
    to->n = 0;
    Py_ssize_t lo = 0;
    while (lo < c->n) {
        Py_ssize_t hi = lo + 1;
        while (hi < c->n && from->query[c->entry[hi]] == from->query[c->entry[lo]]) hi++;
        if (keep_query(s, st, from, c, lo, hi, to) < 0) return -1;
        lo = hi;
    }
    return 0;
}

/* beams(roots, steps, min_probability, most, a, b, c) -> [(query, p, act, parent, lex, state)]
 *   per step, as bytearrays (int64, float64, int64, int64, int64, int64): ActivityPaths._beams.
 *   ROUTINE: a = stay(activity, duration, step) -> float, b = next(labels, current, step) -> (dict,
 *   total), c = first(step) -> dict; OPAQUE: a = distribution(state) -> (dict, last or None),
 *   b = child(state, activity) -> state, c unused. */
static PyObject *paths_beams(Paths *s, PyObject *args) {
    PyObject *o_roots;
    Step st;
    Py_ssize_t steps;
    if (!PyArg_ParseTuple(args, "OndnOOO", &o_roots, &steps, &st.minp, &st.most, &st.stay, &st.next, &st.first)) return NULL;
    if (steps < 0 || st.most < 1) return PyErr_Format(PyExc_ValueError, "forecast core: steps must be >= 0 and most >= 1");
    Buf roots = {0};
    Level from = {0}, to = {0};
    Scratch c = {0};
    PyObject *out = NULL;
    if (buf_get(o_roots, &roots, I64, 0, "roots") < 0) goto done;
    for (Py_ssize_t q = 0; q < roots.n; q++) {
        int64_t id = I64P(roots)[q];
        if (s->kind == OPAQUE && cover(s, (Py_ssize_t)id) < 0) goto done;
        if (id < 0 || id >= s->n) {
            bad("a root state");
            goto done;
        }
        if (level_push(&from, q, 1.0, -1, -1, id) < 0) goto done;
    }
    out = PyList_New(0);
    for (Py_ssize_t t = 0; out && t < steps; t++) {
        if (step_once(s, &st, &from, &c, &to) < 0) goto fail;
        PyObject *lv = level_tuple(&to);
        if (lv == NULL || PyList_Append(out, lv) < 0) {
            Py_XDECREF(lv);
            goto fail;
        }
        Py_DECREF(lv);
        Level swap = from;
        from = to;
        to = swap;
    }
    goto done;
fail:
    Py_CLEAR(out);
done:
    buf_release(&roots);
    level_free(&from);
    level_free(&to);
    scratch_free(&c);
    return out;
}

/* roots(histories) -> bytearray of int64: the state after each history (a sequence of names),
 * numbering new names in the order they first appear (as ActivityPaths.state walks them). */
static PyObject *paths_roots(Paths *s, PyObject *histories) {
    if (s->kind != ROUTINE) return PyErr_Format(PyExc_ValueError, "forecast core: the caller numbers OPAQUE states");
    PyObject *seq = PySequence_Fast(histories, "forecast core: roots takes a sequence of histories");
    if (seq == NULL) return NULL;
    Py_ssize_t nq = PySequence_Fast_GET_SIZE(seq), cap = 0, cap_out = 0;
    int32_t *ids = NULL;
    int64_t *out = NULL;
    PyObject *result = NULL;
    if (reserve((void **)&out, &cap_out, nq ? nq : 1, sizeof(int64_t)) < 0) goto done;
    for (Py_ssize_t q = 0; q < nq; q++) {
        PyObject *h = PySequence_Fast(PySequence_Fast_GET_ITEM(seq, q), "forecast core: a history must be a sequence");
        if (h == NULL) goto done;
        Py_ssize_t n = PySequence_Fast_GET_SIZE(h);
        if (reserve((void **)&ids, &cap, n ? n : 1, sizeof(int32_t)) < 0) {
            Py_DECREF(h);
            goto done;
        }
        for (Py_ssize_t i = 0; i < n; i++)
            if ((ids[i] = local_id(s, PySequence_Fast_GET_ITEM(h, i))) < 0) {
                Py_DECREF(h);
                goto done;
            }
        Py_DECREF(h);
        int32_t tok[MAX_ORDER], labels[MAX_ORDER];
        int64_t start = -1;
        Py_ssize_t count = 0;
        if (n > 0) { /* the current run's start, then the last `order` run labels, newest first */
            Py_ssize_t j = n - 1;
            while (j > 0 && ids[j - 1] == ids[n - 1]) j--;
            start = j;
            labels[count++] = ids[n - 1];
            j--;
            while (count < s->order && j >= 0) {
                int32_t a = ids[j];
                labels[count++] = a;
                while (j >= 0 && ids[j] == a) j--;
            }
        }
        if (count < s->order) labels[count++] = DAY; /* the runs so far are fewer than the order */
        for (Py_ssize_t i = 0; i < s->order; i++) tok[i] = i >= s->order - count ? labels[s->order - 1 - i] : NONE;
        Py_ssize_t id = state_of(s, tok, start, n);
        if (id < 0) goto done;
        out[q] = id;
    }
    result = as_bytes(out, nq, sizeof(int64_t));
done:
    Py_DECREF(seq);
    PyMem_Free(ids);
    PyMem_Free(out);
    return result;
}

static int paths_init(Paths *s, PyObject *args, PyObject *kwds) {
    Py_ssize_t order;
    int kind, step_free;
    PyObject *names, *name_list, *day;
    if (!PyArg_ParseTuple(args, "inpO!O!O", &kind, &order, &step_free, &PyDict_Type, &names, &PyList_Type, &name_list, &day))
        return -1;
    if (kind != ROUTINE && kind != OPAQUE) {
        PyErr_SetString(PyExc_ValueError, "forecast core: the kind must be ROUTINE or OPAQUE");
        return -1;
    }
    if (kind == ROUTINE && (order < 1 || order > MAX_ORDER || !PyUnicode_Check(day))) {
        PyErr_Format(PyExc_ValueError, "forecast core: a routine model's order must be 1..%d, its day token a str", MAX_ORDER);
        return -1;
    }
    if (s->names != NULL) {
        PyErr_SetString(PyExc_RuntimeError, "forecast core: Paths is initialised once");
        return -1;
    }
    s->kind = kind;
    s->order = kind == ROUTINE ? order : 0;
    s->step_free = step_free;
    s->names = Py_NewRef(names);
    s->name_list = Py_NewRef(name_list);
    s->day = Py_NewRef(day);
    s->states.width = order + 2;
    s->stays.width = 3;
    s->runs.width = order + 1;
    if (kind == OPAQUE) return 0;
    int32_t tok[MAX_ORDER];
    for (Py_ssize_t i = 0; i < order; i++) tok[i] = i == order - 1 ? DAY : NONE;
    return state_of(s, tok, -1, 0) == 0 ? 0 : -1; /* the day start is state 0 */
}

static void paths_dealloc(Paths *s) {
    Py_XDECREF(s->names);
    Py_XDECREF(s->name_list);
    Py_XDECREF(s->day);
    void *arrays[] = {s->tok, s->start, s->step, s->first, s->count, s->best, s->ext.act, s->ext.p, s->ext_child, s->stay_values,
                      s->run_items.act, s->run_items.p, s->run_first, s->run_len, s->run_z, s->rank};
    for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); i++) PyMem_Free(arrays[i]);
    table_free(&s->states);
    table_free(&s->stays);
    table_free(&s->runs);
    Py_TYPE(s)->tp_free((PyObject *)s);
}

static PyObject *paths_get_size(Paths *s, void *closure) { return PyLong_FromSsize_t(s->n); }

static PyMethodDef paths_methods[] = {
    {"roots", (PyCFunction)paths_roots, METH_O, "roots(histories) -> bytearray of int64: each history's state"},
    {"beams", (PyCFunction)paths_beams, METH_VARARGS,
     "beams(roots, steps, min_probability, most, stay, next, first) -> the kept paths of each step"},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef paths_getset[] = {
    {"size", (getter)paths_get_size, NULL, "the number of states numbered so far", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject PathsType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "globe.models._forecast_core.Paths",
    .tp_basicsize = sizeof(Paths),
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Paths(kind, order, step_free, names, name_list, day_token): the forward pass over activity paths",
    .tp_new = PyType_GenericNew,
    .tp_init = (initproc)paths_init,
    .tp_dealloc = (destructor)paths_dealloc,
    .tp_methods = paths_methods,
    .tp_getset = paths_getset,
};

/* -- module -------------------------------------------------------------------------------------- */

static PyMethodDef methods[] = {
    {"level", level, METH_VARARGS, "the hazards, survivals and departures of one level of paths (see the module doc)"},
    {"destinations", destinations, METH_VARARGS, "the departures of one level times where they go"},
    {"first_locations", first_locations, METH_VARARGS, "each object's most likely first new place within each horizon"},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_forecast_core",
                                    "The forecaster's hot loops in C (see globe.models.forecast).", -1, methods};

PyMODINIT_FUNC PyInit__forecast_core(void) {
    if (!no_contraction()) {
        PyErr_SetString(PyExc_ImportError, "globe.models._forecast_core was built with fused multiply-adds; "
                                           "rebuild with -ffp-contract=off");
        return NULL;
    }
    if (PyType_Ready(&PathsType) < 0) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    Py_INCREF(&PathsType);
    if (PyModule_AddIntConstant(m, "ROUTINE", ROUTINE) < 0 || PyModule_AddIntConstant(m, "OPAQUE", OPAQUE) < 0 ||
        PyModule_AddObject(m, "Paths", (PyObject *)&PathsType) < 0) {
        Py_DECREF(&PathsType);
        Py_DECREF(m);
        return NULL;
    }
    return m;
}
