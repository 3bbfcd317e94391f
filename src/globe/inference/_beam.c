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

#define KERNEL "beam"
#include "_arrays.h"

/* A weight rounded to 30 significant bits (half to even): equal for weights that differ in their
 * last bits. A finite normal weight is rounded in its bits; zero, subnormals and the rest by frexp. */
static inline double tie_key(double w) {
    uint64_t u;
    memcpy(&u, &w, sizeof u);
    uint64_t exponent = u >> 52 & 0x7ff, low = u & ((1ULL << 23) - 1), half = 1ULL << 22;
    if (exponent == 0 || exponent == 0x7ff) {
        int e;
        double m = frexp(w, &e);
        return ldexp(nearbyint(ldexp(m, 30)), e - 30);
    }
    u -= low;
    if (low > half || (low == half && (u >> 23 & 1))) u += 1ULL << 23; /* a carry moves to the exponent */
    memcpy(&w, &u, sizeof w);
    return w;
}

/* A candidate to sort: by query, then `rank` (0 when sorting by history), then by history in name
 * order (its parent's `lex`, then its activity's name rank), then `index`. */
typedef struct {
    int64_t query;
    uint64_t rank;
    int64_t lex, name, index;
} Item;

static inline int before(const Item *a, const Item *b) {
    if (a->query != b->query) return a->query < b->query;
    if (a->rank != b->rank) return a->rank < b->rank;
    if (a->lex != b->lex) return a->lex < b->lex;
    if (a->name != b->name) return a->name < b->name;
    return a->index < b->index;
}

/* The rank of a weight's key, most probable first (a positive double's bits order it; a weight
 * of 0 comes last: weights are never negative). */
static uint64_t rank_of(double key) {
    uint64_t u;
    memcpy(&u, &key, sizeof u);
    return key > 0.0 ? ~u : UINT64_MAX;
}

/* Sorts items[0..n) (merge sort: runs of 16 by insertion, then merged through `tmp`). */
static void sort_run(Item *items, Item *tmp, Py_ssize_t n) {
    const Py_ssize_t run = 16;
    for (Py_ssize_t lo = 0; lo < n; lo += run) {
        Py_ssize_t hi = lo + run < n ? lo + run : n;
        for (Py_ssize_t i = lo + 1; i < hi; i++) {
            Item x = items[i];
            Py_ssize_t j = i;
            for (; j > lo && before(&x, &items[j - 1]); j--) items[j] = items[j - 1];
            items[j] = x;
        }
    }
    Item *src = items, *dst = tmp;
    for (Py_ssize_t width = run; width < n; width *= 2) {
        for (Py_ssize_t lo = 0; lo < n; lo += 2 * width) {
            Py_ssize_t mid = lo + width < n ? lo + width : n, hi = lo + 2 * width < n ? lo + 2 * width : n;
            Py_ssize_t i = lo, j = mid, k = lo;
            while (i < mid && j < hi) dst[k++] = before(&src[j], &src[i]) ? src[j++] : src[i++];
            while (i < mid) dst[k++] = src[i++];
            while (j < hi) dst[k++] = src[j++];
        }
        Item *t = src;
        src = dst;
        dst = t;
    }
    if (src != items) memcpy(items, src, n * sizeof(Item));
}

/* Sorts items[0..n), which come query by query: each query's apart. */
static void sort_items(Item *items, Item *tmp, Py_ssize_t n) {
    for (Py_ssize_t lo = 0, hi; lo < n; lo = hi) {
        for (hi = lo + 1; hi < n && items[hi].query == items[lo].query; hi++)
            ;
        sort_run(items + lo, tmp, hi - lo);
    }
}

/* The groups of (query, child): group[i] for each candidate, first-seen order; returns how many.
 * The candidates come query by query, so each query's groups are found in a table of its own,
 * small enough to stay in cache. */
typedef struct {
    int64_t child, group;
} Slot;

static Py_ssize_t merge_groups(Py_ssize_t n, Py_ssize_t widest, const int64_t *query, const int64_t *child,
                               int64_t *group) {
    Py_ssize_t cap = 16;
    while (cap < 2 * widest) cap <<= 1;
    Slot *slots = malloc(cap * sizeof(Slot));
    if (!slots) {
        PyErr_NoMemory();
        return -1;
    }
    Py_ssize_t groups = 0;
    for (Py_ssize_t lo = 0, hi; lo < n; lo = hi) {
        for (hi = lo + 1; hi < n && query[hi] == query[lo]; hi++)
            ;
        Py_ssize_t size = 16;
        int shift = 60; /* a slot is the top bits of the child's Fibonacci hash */
        for (; size < 2 * (hi - lo); shift--) size <<= 1;
        for (Py_ssize_t s = 0; s < size; s++) slots[s].group = -1;
        for (Py_ssize_t i = lo; i < hi; i++) {
            Py_ssize_t s = (Py_ssize_t)((uint64_t)child[i] * 0x9E3779B97F4A7C15ULL >> shift);
            while (slots[s].group >= 0 && slots[s].child != child[i]) s = (s + 1) & (size - 1);
            if (slots[s].group < 0) slots[s] = (Slot){child[i], groups++};
            group[i] = slots[s].group;
        }
    }
    free(slots);
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
    const Kind kinds[7] = {I64, I64, I64, F64, I64, I64, I64};
    const char *names_[7] = {"query", "entry", "act", "weight", "child", "lex", "names"};
    Buf b[7] = {0};
    PyObject *out = NULL;
    int64_t *group = NULL, *rep = NULL, *kept_idx = NULL, *kept_lex = NULL;
    double *sum = NULL, *kept_w = NULL, *total = NULL;
    Item *items = NULL, *tmp = NULL;
    for (int i = 0; i < 7; i++)
        if (buf_get(objs[i], &b[i], kinds[i], 0, names_[i]) < 0) goto done;
    Py_ssize_t n = b[0].n;
    const int64_t *query = b[0].view.buf, *entry = b[1].view.buf, *act = b[2].view.buf, *child = b[4].view.buf,
                  *lex = b[5].view.buf, *names = b[6].view.buf;
    const double *w = b[3].view.buf;
    if (b[1].n != n || b[2].n != n || b[3].n != n || (merge && b[4].n != n) || keep < 1 || nq < 0) {
        PyErr_SetString(PyExc_ValueError, "beam: the candidate arrays disagree");
        goto done;
    }
    Py_ssize_t widest = 1; /* the most candidates of a query */
    for (Py_ssize_t i = 0, first = 0; i < n; i++) {
        if (query[i] < 0 || query[i] >= nq || entry[i] < 0 || entry[i] >= b[5].n || act[i] < 0 || act[i] >= b[6].n) {
            PyErr_SetString(PyExc_ValueError, "beam: a candidate's query, entry or activity is out of range");
            goto done;
        }
        if (i && query[i] < query[i - 1]) {
            PyErr_SetString(PyExc_ValueError, "beam: the candidates must come query by query");
            goto done;
        }
        if (query[i] != query[first]) first = i;
        if (i - first + 1 > widest) widest = i - first + 1;
    }
    group = malloc((n ? n : 1) * sizeof(int64_t));
    rep = malloc((n ? n : 1) * sizeof(int64_t));
    sum = malloc((n ? n : 1) * sizeof(double));
    items = malloc((n ? n : 1) * sizeof(Item));
    tmp = malloc(widest * sizeof(Item)); /* a query's items are sorted at a time */
    kept_idx = malloc((n ? n : 1) * sizeof(int64_t));
    kept_w = malloc((n ? n : 1) * sizeof(double));
    kept_lex = malloc((n ? n : 1) * sizeof(int64_t));
    total = calloc(nq ? nq : 1, sizeof(double));
    if (!group || !rep || !sum || !items || !tmp || !kept_idx || !kept_w || !kept_lex || !total) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t groups = n;
    if (merge) {
        groups = merge_groups(n, widest, query, child, group);
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
        items[g] = (Item){query[i], rank_of(tie_key(sum[g])), lex[entry[i]], names[act[i]], g};
    }
    sort_items(items, tmp, groups);
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
        items[r] = (Item){query[i], 0, lex[entry[i]], names[act[i]], r};
    }
    sort_items(items, tmp, k);
    for (Py_ssize_t r = 0, lo = 0; r < k; r++) {
        if (r && items[r].query != items[r - 1].query) lo = r;
        kept_lex[items[r].index] = r - lo;
    }
    for (Py_ssize_t r = 0; r < k; r++) kept_idx[r] = rep[kept_idx[r]];
    out = Py_BuildValue("(NNN)", bytes_of(kept_idx, k), bytes_of(kept_w, k), bytes_of(kept_lex, k));
done:
    for (int i = 0; i < 7; i++) buf_release(&b[i]);
    free(group);
    free(rep);
    free(sum);
    free(items);
    free(tmp);
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
 *   its query's best, history by history (the histories come query by query); a query with a seen
 *   activity (pinned[q] >= 0) extends by it alone. */
static PyObject *extend(PyObject *self, PyObject *args) {
    double floor_;
    Py_ssize_t nq;
    PyObject *objs[7];
    if (!PyArg_ParseTuple(args, "dnOOOOOOO", &floor_, &nq, &objs[0], &objs[1], &objs[2], &objs[3], &objs[4], &objs[5],
                          &objs[6]))
        return NULL;
    const Kind kinds[7] = {F64, F64, I64, I64, F64, I64, I64};
    const char *names_[7] = {"rows", "weight", "query", "pinned", "tables", "table_of", "previous"};
    Buf b[7] = {0};
    PyObject *out = NULL;
    double *cw = NULL;
    int64_t *ce = NULL, *ca = NULL;
    for (int i = 0; i < 7; i++)
        if (buf_get(objs[i], &b[i], kinds[i], 0, names_[i]) < 0) goto done;
    Py_ssize_t n = b[1].n, width = n ? b[0].n / n : 0, ntables = width ? b[4].n / ((width + 1) * width) : 0;
    const double *rows = b[0].view.buf, *weight = b[1].view.buf, *tables = b[4].view.buf;
    const int64_t *query = b[2].view.buf, *pinned = b[3].view.buf, *table_of = b[5].view.buf, *previous = b[6].view.buf;
    int lik = b[4].n > 0;
    if (nq < 0 || (n && b[0].n != n * width) || b[2].n != n || b[3].n != nq ||
        (lik && (b[4].n != ntables * (width + 1) * width || b[5].n != n || b[6].n != n))) {
        PyErr_SetString(PyExc_ValueError, "beam: the extension arrays disagree");
        goto done;
    }
    for (Py_ssize_t r = 0; r < n; r++) {
        if (query[r] < 0 || query[r] >= nq || pinned[query[r]] >= width ||
            (lik && (table_of[r] < 0 || table_of[r] >= ntables || previous[r] < -1 || previous[r] >= width))) {
            PyErr_SetString(PyExc_ValueError, "beam: a history's query, label, table or activity is out of range");
            goto done;
        }
        if (r && query[r] < query[r - 1]) {
            PyErr_SetString(PyExc_ValueError, "beam: the histories must come query by query");
            goto done;
        }
    }
    Py_ssize_t cells = n * width;
    cw = malloc((cells ? cells : 1) * sizeof(double));
    ce = malloc((cells ? cells : 1) * sizeof(int64_t));
    ca = malloc((cells ? cells : 1) * sizeof(int64_t));
    if (!cw || !ce || !ca) {
        PyErr_NoMemory();
        goto done;
    }
    Py_ssize_t m = 0; /* the extensions kept so far; a query's are cut while they are in cache */
    for (Py_ssize_t lo = 0, hi; lo < n; lo = hi) {
        Py_ssize_t k = m;
        double best = 0.0;
        for (hi = lo; hi < n && query[hi] == query[lo]; hi++) {
            const double *row = rows + hi * width;
            const double *lrow = lik ? tables + (table_of[hi] * (width + 1) + (previous[hi] < 0 ? width : previous[hi])) * width : NULL;
            int64_t only = pinned[query[hi]];
            for (Py_ssize_t a = only >= 0 ? only : 0; a < (only >= 0 ? only + 1 : width); a++) {
                if (!(row[a] > 0.0)) continue;
                double x = weight[hi] * row[a];
                if (lrow) x = x * lrow[a];
                if (!(x > 0.0)) continue;
                cw[k] = x;
                ce[k] = hi;
                ca[k++] = a;
                if (x > best) best = x;
            }
        }
        for (Py_ssize_t i = m, end = k; i < end; i++)
            if (cw[i] >= floor_ * best) {
                cw[m] = cw[i];
                ce[m] = ce[i];
                ca[m++] = ca[i];
            }
    }
    out = Py_BuildValue("(NNN)", bytes_of(ce, m), bytes_of(ca, m), bytes_of(cw, m));  /* N: a NULL fails it cleanly */
done:
    for (int i = 0; i < 7; i++) buf_release(&b[i]);
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
    const Kind kinds[5] = {F64, F64, I64, I64, I64};
    const char *names_[5] = {"rows", "weight", "query", "lex", "names"};
    Buf b[5] = {0};
    PyObject *out = NULL;
    double *cw = NULL, *fw = NULL;
    int64_t *ce = NULL, *ca = NULL, *fe = NULL, *fa = NULL;
    char *found = NULL;
    for (int i = 0; i < 5; i++)
        if (buf_get(objs[i], &b[i], kinds[i], 0, names_[i]) < 0) goto done;
    Py_ssize_t n = b[1].n, width = n ? b[0].n / n : 0;
    const double *rows = b[0].view.buf, *weight = b[1].view.buf;
    const int64_t *query = b[2].view.buf, *lex = b[3].view.buf, *names = b[4].view.buf;
    if (nq < 0 || (n && b[0].n != n * width) || b[2].n != n || b[3].n != n || b[4].n < width) {
        PyErr_SetString(PyExc_ValueError, "beam: the extension arrays disagree");
        goto done;
    }
    for (Py_ssize_t r = 0; r < n; r++)
        if (query[r] < 0 || query[r] >= nq || (r && query[r] < query[r - 1])) {
            PyErr_SetString(PyExc_ValueError, "beam: a path's query is out of range or out of order");
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
    for (int i = 0; i < 5; i++) buf_release(&b[i]);
    free(cw);
    free(ce);
    free(ca);
    free(fw);
    free(fe);
    free(fa);
    free(found);
    return out;
}

/* tie_key(weights) -> bytes of float64: each weight rounded as the selection compares them. */
static PyObject *tie_keys(PyObject *self, PyObject *arg) {
    Buf b = {0};
    if (buf_get(arg, &b, F64, 0, "weights") < 0) {
        buf_release(&b);
        return NULL;
    }
    PyObject *out = PyBytes_FromStringAndSize(NULL, b.n * 8);
    if (out) {
        double *keys = (double *)PyBytes_AS_STRING(out);
        const double *w = b.view.buf;
        for (Py_ssize_t i = 0; i < b.n; i++) keys[i] = tie_key(w[i]);
    }
    buf_release(&b);
    return out;
}

static PyMethodDef methods[] = {
    {"tie_key", tie_keys, METH_O, "Weights rounded to 30 significant bits, as the selection compares them."},
    {"select", select_, METH_VARARGS, "Merge, rank, cut and renormalise a beam's extensions."},
    {"extend", extend, METH_VARARGS, "The filter's extensions above its floor."},
    {"extend_paths", extend_paths, METH_VARARGS, "The forecaster's path extensions above the floor."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_beam", NULL, -1, methods};

PyMODINIT_FUNC PyInit__beam(void) { return PyModule_Create(&module); }
