/* The beam step's selection: merge, rank, cut and renormalise extensions, query by query.
 *
 * globe/inference/beam.py computes every extension of a beam (its history's entry, activity,
 * weight and, for the filter, the state it reaches) with numpy and the model's state space; this
 * kernel, the only implementation of the selection, then
 *   - when merging (merge = 1), merges the extensions that reach the same state of the same
 *     query: weights summed in input order, the first of the most probable representing the group
 *     (extend() makes the filter's extensions, dropping those below `floor` times their query's best);
 *   - ranks each query's candidates: most probable first (weights compared rounded to 30
 *     significant bits, so a last bit never decides), then by history in name order (the
 *     parent's rank `lex`, then the activity's name rank);
 *   - keeps the `keep` first of each query and, when merging, those at least `floor` of the kept
 *     total (the first always); without merging, a query that had no more than `keep` keeps its
 *     candidates in input order;
 *   - renormalises each query (summed in the kept order) and ranks the kept histories in name
 *     order (`lex` of the next step).
 * select(merge, keep, floor, queries, query, entry, act, weight, child, lex, names)
 *   -> (index of each kept candidate (the representative) in output order, its weight, its lex)
 * as bytes of int64, float64 and int64. Every index read from an argument is checked first.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    Py_buffer view;
    Py_ssize_t n;
    int held;
} Buf;

static int get_buf(PyObject *obj, Buf *b, char kind, const char *what) {
    if (PyObject_GetBuffer(obj, &b->view, PyBUF_C_CONTIGUOUS | PyBUF_FORMAT) < 0) return -1;
    b->held = 1;
    const char *f = b->view.format ? b->view.format : "B";
    if (*f == '@' || *f == '=' || *f == '<') f++;
    int ok = kind == 'd' ? (f[0] == 'd' && b->view.itemsize == 8) : ((f[0] == 'l' || f[0] == 'q') && b->view.itemsize == 8);
    if (!ok || f[1] != 0) {
        PyErr_Format(PyExc_ValueError, "beam: %s must be a contiguous %s array", what, kind == 'd' ? "float64" : "int64");
        return -1;
    }
    b->n = b->view.len / 8;
    return 0;
}

static void release(Buf *b) {
    if (b->held) PyBuffer_Release(&b->view);
    b->held = 0;
}

/* A weight rounded to 30 significant bits: equal for weights that differ in their last bits. */
static double tie_key(double w) {
    int e;
    double m = frexp(w, &e);
    return ldexp(nearbyint(ldexp(m, 30)), e - 30);
}

typedef struct {
    int64_t query, lex, name, index;
    double key;
} Item;

static int by_rank(const void *pa, const void *pb) { /* query, most probable first, then by history */
    const Item *a = pa, *b = pb;
    if (a->query != b->query) return a->query < b->query ? -1 : 1;
    if (a->key != b->key) return a->key > b->key ? -1 : 1;
    if (a->lex != b->lex) return a->lex < b->lex ? -1 : 1;
    if (a->name != b->name) return a->name < b->name ? -1 : 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

static int by_history(const void *pa, const void *pb) { /* query, then by history in name order */
    const Item *a = pa, *b = pb;
    if (a->query != b->query) return a->query < b->query ? -1 : 1;
    if (a->lex != b->lex) return a->lex < b->lex ? -1 : 1;
    if (a->name != b->name) return a->name < b->name ? -1 : 1;
    return a->index < b->index ? -1 : a->index > b->index;
}

/* The groups of (query, child): group[i] for each candidate, first-seen order; returns how many. */
static Py_ssize_t merge_groups(Py_ssize_t n, const int64_t *query, const int64_t *child, int64_t *group) {
    Py_ssize_t size = 16;
    while (size < 2 * n) size <<= 1;
    int64_t *slot_q = malloc(size * sizeof(int64_t)), *slot_c = malloc(size * sizeof(int64_t)),
            *slot_g = malloc(size * sizeof(int64_t));
    if (!slot_q || !slot_c || !slot_g) {
        free(slot_q);
        free(slot_c);
        free(slot_g);
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t s = 0; s < size; s++) slot_g[s] = -1;
    Py_ssize_t groups = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        uint64_t h = (uint64_t)query[i] * 0x9E3779B97F4A7C15ULL ^ (uint64_t)child[i] * 0xC2B2AE3D27D4EB4FULL;
        h ^= h >> 29;
        Py_ssize_t s = (Py_ssize_t)(h & (uint64_t)(size - 1));
        while (slot_g[s] >= 0 && (slot_q[s] != query[i] || slot_c[s] != child[i])) s = (s + 1) & (size - 1);
        if (slot_g[s] < 0) {
            slot_q[s] = query[i];
            slot_c[s] = child[i];
            slot_g[s] = groups++;
        }
        group[i] = slot_g[s];
    }
    free(slot_q);
    free(slot_c);
    free(slot_g);
    return groups;
}

/* n int64 or float64 values as bytes (NULL on failure: Py_BuildValue's "N" then fails cleanly) */
static PyObject *bytes_of(const void *p, Py_ssize_t n) { return PyBytes_FromStringAndSize(n ? (const char *)p : "", n * 8); }

static PyObject *select_(PyObject *self, PyObject *args) {
    int merge;
    Py_ssize_t keep, nq;
    double floor_;
    PyObject *objs[7];
    if (!PyArg_ParseTuple(args, "pndnOOOOOOO", &merge, &keep, &floor_, &nq, &objs[0], &objs[1], &objs[2], &objs[3],
                          &objs[4], &objs[5], &objs[6]))
        return NULL;
    const char kinds[7] = {'q', 'q', 'q', 'd', 'q', 'q', 'q'};
    const char *names_[7] = {"query", "entry", "act", "weight", "child", "lex", "names"};
    Buf b[7] = {{0}};
    PyObject *out = NULL;
    int64_t *group = NULL, *rep = NULL, *kept_idx = NULL, *kept_lex = NULL;
    double *sum = NULL, *kept_w = NULL, *total = NULL;
    Item *items = NULL;
    for (int i = 0; i < 7; i++)
        if (get_buf(objs[i], &b[i], kinds[i], names_[i]) < 0) goto done;
    Py_ssize_t n = b[0].n;
    const int64_t *query = b[0].view.buf, *entry = b[1].view.buf, *act = b[2].view.buf, *child = b[4].view.buf,
                  *lex = b[5].view.buf, *names = b[6].view.buf;
    const double *w = b[3].view.buf;
    if (b[1].n != n || b[2].n != n || b[3].n != n || (merge && b[4].n != n) || keep < 1 || nq < 0) {
        PyErr_SetString(PyExc_ValueError, "beam: the candidate arrays disagree");
        goto done;
    }
    for (Py_ssize_t i = 0; i < n; i++)
        if (query[i] < 0 || query[i] >= nq || entry[i] < 0 || entry[i] >= b[5].n || act[i] < 0 || act[i] >= b[6].n ||
            (i && query[i] < query[i - 1])) {
            PyErr_SetString(PyExc_ValueError, "beam: a candidate's query, entry or activity is out of range");
            goto done;
        }
    group = malloc((n ? n : 1) * sizeof(int64_t));
    rep = malloc((n ? n : 1) * sizeof(int64_t));
    sum = malloc((n ? n : 1) * sizeof(double));
    items = malloc((n ? n : 1) * sizeof(Item));
    kept_idx = malloc((n ? n : 1) * sizeof(int64_t));
    kept_w = malloc((n ? n : 1) * sizeof(double));
    kept_lex = malloc((n ? n : 1) * sizeof(int64_t));
    total = calloc(nq ? nq : 1, sizeof(double));
    if (!group || !rep || !sum || !items || !kept_idx || !kept_w || !kept_lex || !total) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t groups = n;
    if (merge) {
        groups = merge_groups(n, query, child, group);
        if (groups < 0) goto done;
        for (Py_ssize_t g = 0; g < groups; g++) {
            rep[g] = -1;
            sum[g] = 0.0;
        }
        for (Py_ssize_t i = 0; i < n; i++) {
            int64_t g = group[i];
            double key = tie_key(w[i]);
            sum[g] += w[i];
            if (rep[g] < 0 || key > kept_w[g]) { /* kept_w holds each group's best key until the output */
                rep[g] = i;
                kept_w[g] = key;
            }
        }
    } else {
        for (Py_ssize_t i = 0; i < n; i++) {
            rep[i] = i;
            sum[i] = w[i];
        }
    }
    for (Py_ssize_t g = 0; g < groups; g++) {
        int64_t i = rep[g];
        items[g] = (Item){query[i], lex[entry[i]], names[act[i]], g, tie_key(sum[g])};
    }
    /* the groups come query by query (the candidates do, and a group is numbered when first seen):
     * each query's are sorted apart */
    for (Py_ssize_t lo = 0, hi; lo < groups; lo = hi) {
        for (hi = lo + 1; hi < groups && items[hi].query == items[lo].query; hi++)
            ;
        qsort(items + lo, hi - lo, sizeof(Item), by_rank);
    }
    /* each query's first `keep`; when merging, those at least `floor` of their total */
    Py_ssize_t k = 0;
    for (Py_ssize_t lo = 0; lo < groups;) {
        Py_ssize_t hi = lo;
        while (hi < groups && items[hi].query == items[lo].query) hi++;
        Py_ssize_t top = hi - lo < keep ? hi - lo : keep;
        double kept_total = 0.0;
        for (Py_ssize_t r = 0; r < top; r++) kept_total += sum[items[lo + r].index];
        if (merge) {
            for (Py_ssize_t r = 0; r < top; r++)
                if (r == 0 || sum[items[lo + r].index] >= floor_ * kept_total) kept_idx[k++] = items[lo + r].index;
        } else if (hi - lo <= keep) { /* not cut: the candidates keep their input order */
            Py_ssize_t first = k;
            for (Py_ssize_t r = 0; r < top; r++) kept_idx[k++] = items[lo + r].index;
            for (Py_ssize_t a = first + 1; a < k; a++) { /* insertion sort back into input order */
                int64_t v = kept_idx[a];
                Py_ssize_t c = a;
                while (c > first && kept_idx[c - 1] > v) {
                    kept_idx[c] = kept_idx[c - 1];
                    c--;
                }
                kept_idx[c] = v;
            }
        } else {
            for (Py_ssize_t r = 0; r < top; r++) kept_idx[k++] = items[lo + r].index;
        }
        lo = hi;
    }
    for (Py_ssize_t r = 0; r < k; r++) total[query[rep[kept_idx[r]]]] += sum[kept_idx[r]];
    for (Py_ssize_t r = 0; r < k; r++) {
        int64_t g = kept_idx[r], i = rep[g];
        kept_w[r] = sum[g] / total[query[i]];
        items[r] = (Item){query[i], lex[entry[i]], names[act[i]], r, 0.0};
    }
    for (Py_ssize_t lo = 0, hi; lo < k; lo = hi) {
        for (hi = lo + 1; hi < k && items[hi].query == items[lo].query; hi++)
            ;
        qsort(items + lo, hi - lo, sizeof(Item), by_history);
    }
    for (Py_ssize_t r = 0, lo = 0; r < k; r++) {
        if (r && items[r].query != items[r - 1].query) lo = r;
        kept_lex[items[r].index] = r - lo;
    }
    for (Py_ssize_t r = 0; r < k; r++) kept_idx[r] = rep[kept_idx[r]];
    out = Py_BuildValue("(NNN)", bytes_of(kept_idx, k), bytes_of(kept_w, k), bytes_of(kept_lex, k));
done:
    for (int i = 0; i < 7; i++) release(&b[i]);
    free(group);
    free(rep);
    free(sum);
    free(items);
    free(kept_idx);
    free(kept_w);
    free(kept_lex);
    free(total);
    return out;
}

/* extend(floor, queries, rows, weight, query, pinned, tables, table_of, previous)
 *   -> (entry, act, weight) as int64, int64, float64 bytes: every extension of the filter's
 *   histories (row r of `rows`, the next-step distribution of history r, times its weight and,
 *   when `tables` is not empty, the movement likelihood tables[table_of[r], previous[r], act],
 *   where previous -1 reads the table's last row) with weight above 0 and at least `floor` times
 *   its query's best, history by history; a query with a seen activity (pinned[q] >= 0) extends
 *   by it alone. */
static PyObject *extend(PyObject *self, PyObject *args) {
    double floor_;
    Py_ssize_t nq;
    PyObject *objs[7];
    if (!PyArg_ParseTuple(args, "dnOOOOOOO", &floor_, &nq, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5],
                          &objs[6]))
        return NULL;
    const char kinds[7] = {'d', 'd', 'q', 'q', 'd', 'q', 'q'};
    const char *names_[7] = {"rows", "weight", "query", "pinned", "tables", "table_of", "previous"};
    Buf b[7] = {{0}};
    PyObject *out = NULL;
    double *best = NULL, *cw = NULL;
    int64_t *ce = NULL, *ca = NULL;
    for (int i = 0; i < 7; i++)
        if (get_buf(objs[i], &b[i], kinds[i], names_[i]) < 0) goto done;
    Py_ssize_t n = b[1].n, width = n ? b[0].n / n : 0, ntables = width ? b[4].n / ((width + 1) * width) : 0;
    const double *rows = b[0].view.buf, *weight = b[1].view.buf, *tables = b[4].view.buf;
    const int64_t *query = b[2].view.buf, *pinned = b[3].view.buf, *table_of = b[5].view.buf, *previous = b[6].view.buf;
    int lik = b[4].n > 0;
    if (nq < 0 || (n && b[0].n != n * width) || b[2].n != n || b[3].n != nq ||
        (lik && (b[4].n != ntables * (width + 1) * width || b[5].n != n || b[6].n != n))) {
        PyErr_SetString(PyExc_ValueError, "beam: the extension arrays disagree");
        goto done;
    }
    for (Py_ssize_t r = 0; r < n; r++)
        if (query[r] < 0 || query[r] >= nq || pinned[query[r]] >= width ||
            (lik && (table_of[r] < 0 || table_of[r] >= ntables || previous[r] < -1 || previous[r] >= width))) {
            PyErr_SetString(PyExc_ValueError, "beam: a history's query, label, table or activity is out of range");
            goto done;
        }
    Py_ssize_t cells = n * width;
    best = calloc(nq ? nq : 1, sizeof(double));
    cw = malloc((cells ? cells : 1) * sizeof(double));
    ce = malloc((cells ? cells : 1) * sizeof(int64_t));
    ca = malloc((cells ? cells : 1) * sizeof(int64_t));
    if (!best || !cw || !ce || !ca) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t k = 0;
    for (Py_ssize_t r = 0; r < n; r++) {
        const double *row = rows + r * width;
        const double *lrow = lik ? tables + (table_of[r] * (width + 1) + (previous[r] < 0 ? width : previous[r])) * width : NULL;
        int64_t only = pinned[query[r]];
        for (Py_ssize_t a = only >= 0 ? only : 0; a < (only >= 0 ? only + 1 : width); a++) {
            if (!(row[a] > 0.0)) continue;
            double x = weight[r] * row[a];
            if (lrow) x = x * lrow[a];
            if (!(x > 0.0)) continue;
            cw[k] = x;
            ce[k] = r;
            ca[k++] = a;
            if (x > best[query[r]]) best[query[r]] = x;
        }
    }
    Py_ssize_t m = 0;
    for (Py_ssize_t i = 0; i < k; i++)
        if (cw[i] >= floor_ * best[query[ce[i]]]) {
            cw[m] = cw[i];
            ce[m] = ce[i];
            ca[m++] = ca[i];
        }
    out = Py_BuildValue("(NNN)", bytes_of(ce, m), bytes_of(ca, m), bytes_of(cw, m));  /* N: a NULL fails it cleanly */
done:
    for (int i = 0; i < 7; i++) release(&b[i]);
    free(best);
    free(cw);
    free(ce);
    free(ca);
    return out;
}

/* extend_paths(floor, queries, rows, weight, query, lex, names) -> (entry, act, weight) bytes: every
 * extension of the forecaster's paths (row r of `rows` times its weight) with weight at least
 * `floor`, path by path in activity order; a query with none keeps one, the most probable of its
 * paths' most probable next activities (ties: the path first in name order, `lex`). A path's
 * most probable next activity is its row's largest (ties: the larger name rank, `names`). */
static PyObject *extend_paths(PyObject *self, PyObject *args) {
    double floor_;
    Py_ssize_t nq;
    PyObject *objs[5];
    if (!PyArg_ParseTuple(args, "dnOOOOO", &floor_, &nq, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4])) return NULL;
    const char kinds[5] = {'d', 'd', 'q', 'q', 'q'};
    const char *names_[5] = {"rows", "weight", "query", "lex", "names"};
    Buf b[5] = {{0}};
    PyObject *out = NULL;
    double *cw = NULL, *fw = NULL;
    int64_t *ce = NULL, *ca = NULL, *fe = NULL, *fa = NULL;
    char *found = NULL;
    for (int i = 0; i < 5; i++)
        if (get_buf(objs[i], &b[i], kinds[i], names_[i]) < 0) goto done;
    Py_ssize_t n = b[1].n, width = n ? b[0].n / n : 0;
    const double *rows = b[0].view.buf, *weight = b[1].view.buf;
    const int64_t *query = b[2].view.buf, *lex = b[3].view.buf, *names = b[4].view.buf;
    if (nq < 0 || (n && b[0].n != n * width) || b[2].n != n || b[3].n != n || b[4].n < width) {
        PyErr_SetString(PyExc_ValueError, "beam: the extension arrays disagree");
        goto done;
    }
    for (Py_ssize_t r = 0; r < n; r++)
        if (query[r] < 0 || query[r] >= nq || (r && query[r] < query[r - 1])) {
            PyErr_SetString(PyExc_ValueError, "beam: a path's query is out of range");
            goto done;
        }
    Py_ssize_t cells = n * width;
    cw = malloc((cells ? cells : 1) * sizeof(double));
    ce = malloc((cells ? cells : 1) * sizeof(int64_t));
    ca = malloc((cells ? cells : 1) * sizeof(int64_t));
    fw = malloc((nq ? nq : 1) * sizeof(double)); /* each query's fallback: weight, entry, activity */
    fe = malloc((nq ? nq : 1) * sizeof(int64_t));
    fa = malloc((nq ? nq : 1) * sizeof(int64_t));
    found = calloc(nq ? nq : 1, 1);
    if (!cw || !ce || !ca || !fw || !fe || !fa || !found) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t q = 0; q < nq; q++) fe[q] = -1;
    Py_ssize_t k = 0;
    for (Py_ssize_t r = 0; r < n; r++) {
        const double *row = rows + r * width;
        Py_ssize_t best = -1;
        for (Py_ssize_t a = 0; a < width; a++)
            if (row[a] > 0.0 && (best < 0 || row[a] > row[best] || (row[a] == row[best] && names[a] > names[best]))) best = a;
        for (Py_ssize_t a = 0; a < width; a++) {
            if (!(row[a] > 0.0)) continue;
            double x = weight[r] * row[a];
            if (x >= floor_) {
                cw[k] = x;
                ce[k] = r;
                ca[k++] = a;
                found[query[r]] = 1;
            } else if (a == best) {
                int64_t q = query[r], e = fe[q];
                double kx = tie_key(x), ke = e >= 0 ? tie_key(fw[q]) : 0.0;
                if (e < 0 || kx > ke || (kx == ke && (lex[r] < lex[e] || (lex[r] == lex[e] && names[a] < names[fa[q]])))) {
                    fw[q] = x;
                    fe[q] = r;
                    fa[q] = a;
                }
            }
        }
    }
    Py_ssize_t extra = 0;
    for (Py_ssize_t q = 0; q < nq; q++) extra += !found[q] && fe[q] >= 0;
    if (extra) { /* the fallbacks, in their place: history by history */
        Py_ssize_t total = k + extra, i = k - 1, j = total - 1;
        double *w2 = realloc(cw, total * sizeof(double));
        if (w2) cw = w2;
        int64_t *e2 = realloc(ce, total * sizeof(int64_t));
        if (e2) ce = e2;
        int64_t *a2 = realloc(ca, total * sizeof(int64_t));
        if (a2) ca = a2;
        if (!w2 || !e2 || !a2) {
            PyErr_NoMemory();
            goto done;
        }
        for (Py_ssize_t q = nq - 1; q >= 0; q--) {
            if (found[q] || fe[q] < 0) continue;
            while (i >= 0 && (ce[i] > fe[q] || (ce[i] == fe[q] && ca[i] > fa[q]))) {
                cw[j] = cw[i];
                ce[j] = ce[i];
                ca[j--] = ca[i--];
            }
            cw[j] = fw[q];
            ce[j] = fe[q];
            ca[j--] = fa[q];
        }
        k = total;
    }
    out = Py_BuildValue("(NNN)", bytes_of(ce, k), bytes_of(ca, k), bytes_of(cw, k));  /* N: a NULL fails it cleanly */
done:
    for (int i = 0; i < 5; i++) release(&b[i]);
    free(cw);
    free(ce);
    free(ca);
    free(fw);
    free(fe);
    free(fa);
    free(found);
    return out;
}

static PyMethodDef methods[] = {
    {"select", select_, METH_VARARGS, "Merge, rank, cut and renormalise a beam's extensions."},
    {"extend", extend, METH_VARARGS, "The filter's extensions above its floor."},
    {"extend_paths", extend_paths, METH_VARARGS, "The forecaster's path extensions above the floor."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_beam", NULL, -1, methods};

PyMODINIT_FUNC PyInit__beam(void) { return PyModule_Create(&module); }
