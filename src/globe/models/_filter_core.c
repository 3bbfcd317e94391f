/* The activity filter's step in C: the hot path of globe.models.activity_filter.ActivityFilter.
 *
 * ActivityFilter._advance, predictive and posterior do, per step and per kept history, a few
 * dict lookups, multiplications and merges: in Python that is most of the missing-label stage.
 * This module does the same arithmetic, in the same order, on arrays, so every weight has the
 * same bits as in Python (tested side by side over HOMER+ days); the Python code stays the
 * reference, and the fallback where this module is not compiled. Optional.
 *
 * Core: one per fitted model's dynamics, shared by its filters. It numbers activities (`rank`
 * orders the numbers as their names sort, so histories compare as tuples of names do) and
 * states ("keys": histories with the same future), and remembers each (key, step)'s
 * next-activity distribution. For the routine model a key is the last `order` run labels and
 * the current run's start; its children are computed here, its distribution mixed here from two
 * parts asked from Python once each (_RoutineDynamics.stay and next_runs) exactly as
 * _RoutineDynamics._compute mixes them. For the n-gram and persistence models the key is the
 * dynamics' cursor: children and distributions are asked from the dynamics, then remembered.
 * Beam: the histories kept after a step. Immutable (a shallow copy of a filter shares it, each
 * step makes a new one). Each history is a Node (its last activity, its parent); the dynamics'
 * cursor of a routine history is only built when asked (hypotheses(), or a memo miss).
 * Contexts and Evidence: MovementEmission's likelihoods. Contexts holds, per core and emission
 * counts, each (part, activity, change flag, following activity) context's log P(nothing moved)
 * and log-odds per object, each asked from Python once (the same floats); Evidence, per emission
 * setting, each moved set's upper bound and likelihood rows, combined from them exactly as
 * MovementEmission.upper_bound and log_likelihood do.
 *
 * Floating point: products and sums are never fused (setup.py builds with -ffp-contract=off;
 * checked at import), sums of several floats add as this interpreter's sum() does (probed at
 * import), exp and log are the C library's, as Python's math module's are. Every number read
 * back from a memo or from Python is checked before it indexes anything.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "_c_common.h"

#if defined(__clang__)
#pragma STDC FP_CONTRACT OFF /* GCC ignores it: setup.py passes -ffp-contract=off */
#endif

enum { ROUTINE = 0, OPAQUE = 1 };
enum { FLAG_NONE = 0, FLAG_FALSE = 1, FLAG_TRUE = 2 }; /* a movement's change flag: None, False, True */

#define DIST_LIMIT 200000  /* distributions a core remembers before it starts over (as the dynamics' memo) */
#define CHILD_LIMIT 200000 /* children of opaque keys a core remembers before it starts over */
#define MOVED_LIMIT 20000  /* moved sets an evidence remembers before it starts over (as MovementEmission) */
#define STAY_LIMIT 1000000 /* routine: stay probabilities a core remembers before it starts over */
#define TOKENS_ONLY (-2)   /* routine: the "start" of a key that stands for its run labels alone */

static PyObject *s_advance, *s_start, *s_key; /* method names */

/* -- sums, as this interpreter's sum() adds floats --------------------------------------------- */

static int compensated_sum; /* 1 where sum() compensates rounding (Python 3.12 and later): probed at import */

static double float_sum(const double *x, Py_ssize_t n) {
    if (n <= 0) return 0.0;
    double s = 0.0 + x[0], c = 0.0; /* sum() starts from the int 0 */
    for (Py_ssize_t i = 1; i < n; i++) {
        if (!compensated_sum) {
            s += x[i];
            continue;
        }
        double t = s + x[i];
        if (fabs(s) >= fabs(x[i]))
            c += (s - t) + x[i];
        else
            c += (x[i] - t) + s;
        s = t;
    }
    if (compensated_sum && c != 0.0 && isfinite(c)) s += c;
    return s;
}

/* -- a hash map from three integers to one ------------------------------------------------------ */

#define MAP_EMPTY INT64_MIN

typedef struct {
    int64_t *keys; /* 3 per slot; MAP_EMPTY first: a free slot */
    int64_t *values;
    Py_ssize_t cap, n;
} Map;

static uint64_t hash3(int64_t a, int64_t b, int64_t c) {
    uint64_t h = mix64((uint64_t)a * 0x9E3779B97F4A7C15ULL + 1);
    h = mix64(h ^ ((uint64_t)b * 0xBF58476D1CE4E5B9ULL + 2));
    return mix64(h ^ ((uint64_t)c * 0xD6E8FEB86659FD93ULL + 3));
}

static int map_get(const Map *m, int64_t a, int64_t b, int64_t c, int64_t *out) {
    if (m->cap == 0) return 0;
    size_t mask = (size_t)m->cap - 1, i = (size_t)hash3(a, b, c) & mask;
    for (;;) {
        const int64_t *k = m->keys + 3 * i;
        if (k[0] == MAP_EMPTY) return 0;
        if (k[0] == a && k[1] == b && k[2] == c) {
            *out = m->values[i];
            return 1;
        }
        i = (i + 1) & mask;
    }
}

static void map_place(int64_t *keys, int64_t *values, Py_ssize_t cap, const int64_t *k, int64_t v) {
    size_t mask = (size_t)cap - 1, i = (size_t)hash3(k[0], k[1], k[2]) & mask;
    while (keys[3 * i] != MAP_EMPTY && !(keys[3 * i] == k[0] && keys[3 * i + 1] == k[1] && keys[3 * i + 2] == k[2]))
        i = (i + 1) & mask;
    memcpy(keys + 3 * i, k, 3 * sizeof(int64_t));
    values[i] = v;
}

static int map_put(Map *m, int64_t a, int64_t b, int64_t c, int64_t v) {
    if (a == MAP_EMPTY) {
        PyErr_SetString(PyExc_OverflowError, "filter core: a number out of range");
        return -1;
    }
    if (2 * (m->n + 1) > m->cap) {
        Py_ssize_t cap = m->cap ? 2 * m->cap : 64;
        int64_t *keys = PyMem_Malloc((size_t)cap * 3 * sizeof(int64_t));
        int64_t *values = PyMem_Malloc((size_t)cap * sizeof(int64_t));
        if (keys == NULL || values == NULL) {
            PyMem_Free(keys);
            PyMem_Free(values);
            PyErr_NoMemory();
            return -1;
        }
        for (Py_ssize_t i = 0; i < cap; i++) keys[3 * i] = MAP_EMPTY;
        for (Py_ssize_t i = 0; i < m->cap; i++)
            if (m->keys[3 * i] != MAP_EMPTY) map_place(keys, values, cap, m->keys + 3 * i, m->values[i]);
        PyMem_Free(m->keys);
        PyMem_Free(m->values);
        m->keys = keys;
        m->values = values;
        m->cap = cap;
    }
    int64_t seen;
    if (!map_get(m, a, b, c, &seen)) m->n++;
    const int64_t k[3] = {a, b, c};
    map_place(m->keys, m->values, m->cap, k, v);
    return 0;
}

static void map_clear(Map *m) {
    for (Py_ssize_t i = 0; i < m->cap; i++) m->keys[3 * i] = MAP_EMPTY;
    m->n = 0;
}

static void map_free(Map *m) {
    PyMem_Free(m->keys);
    PyMem_Free(m->values);
    memset(m, 0, sizeof(Map));
}

/* -- remembered distributions -------------------------------------------------------------------- */

typedef struct { /* activities and their probabilities, distribution after distribution */
    Py_ssize_t n, cap;
    int32_t *act;
    double *p;
} Items;

typedef struct { /* the distributions in Items: where each starts, its length, and a number (a total) */
    Py_ssize_t n, cap;
    Py_ssize_t *first, *len;
    double *z;
} Spans;

typedef struct { /* distributions by three numbers; starts over when `limit` are remembered */
    Map index;
    Items items;
    Spans spans;
    Py_ssize_t limit;
} Memo;

static int items_reserve(Items *t, Py_ssize_t need) {
    if (need <= t->cap) return 0;
    Py_ssize_t cap = t->cap ? t->cap : 1024;
    while (cap < need) cap *= 2;
    int32_t *act = PyMem_Realloc(t->act, (size_t)cap * sizeof(int32_t));
    if (act) t->act = act;
    double *p = PyMem_Realloc(t->p, (size_t)cap * sizeof(double));
    if (p) t->p = p;
    if (!act || !p) {
        PyErr_NoMemory();
        return -1;
    }
    t->cap = cap;
    return 0;
}

/* Make room for one more distribution (starting over when full); 0, or -1 on error. */
static int memo_open(Memo *m, Py_ssize_t items) {
    if (m->spans.n >= m->limit) {
        map_clear(&m->index);
        m->items.n = m->spans.n = 0;
    }
    if (items_reserve(&m->items, m->items.n + items) < 0) return -1;
    Spans *s = &m->spans;
    if (s->n < s->cap) return 0;
    Py_ssize_t cap = s->cap ? 2 * s->cap : 256;
    Py_ssize_t *first = PyMem_Realloc(s->first, (size_t)cap * sizeof(Py_ssize_t));
    if (first) s->first = first;
    Py_ssize_t *len = PyMem_Realloc(s->len, (size_t)cap * sizeof(Py_ssize_t));
    if (len) s->len = len;
    double *z = PyMem_Realloc(s->z, (size_t)cap * sizeof(double));
    if (z) s->z = z;
    if (!first || !len || !z) {
        PyErr_NoMemory();
        return -1;
    }
    s->cap = cap;
    return 0;
}

/* Close the distribution of the items added since `first` (after memo_open) under (a, b, c). */
static Py_ssize_t memo_close(Memo *m, Py_ssize_t first, double z, int64_t a, int64_t b, int64_t c) {
    Spans *s = &m->spans;
    s->first[s->n] = first;
    s->len[s->n] = m->items.n - first;
    s->z[s->n] = z;
    if (map_put(&m->index, a, b, c, s->n) < 0) return -1;
    return s->n++;
}

static int memo_get(const Memo *m, int64_t a, int64_t b, int64_t c, Py_ssize_t *out) {
    int64_t found;
    if (!map_get(&m->index, a, b, c, &found)) return 0;
    if (found < 0 || found >= m->spans.n) return 0; /* (never: numbers come from memo_close) */
    *out = (Py_ssize_t)found;
    return 1;
}

static void memo_free(Memo *m) {
    map_free(&m->index);
    PyMem_Free(m->items.act);
    PyMem_Free(m->items.p);
    PyMem_Free(m->spans.first);
    PyMem_Free(m->spans.len);
    PyMem_Free(m->spans.z);
}

/* A number stored in one of this module's own dicts, checked to be in [0, n) before it is used. */
static Py_ssize_t stored_number(PyObject *number, Py_ssize_t n) {
    Py_ssize_t v = PyLong_AsSsize_t(number);
    if (v == -1 && PyErr_Occurred()) return -1;
    if (v < 0 || v >= n) {
        PyErr_SetString(PyExc_RuntimeError, "filter core: a stored number is out of range");
        return -1;
    }
    return v;
}

/* -- Core --------------------------------------------------------------------------------------- */

typedef struct { /* the extensions scored in a step, in order */
    Py_ssize_t n, cap, pcap, acap;
    double *w;
    Py_ssize_t *parent;
    int32_t *act;
} Grown;

typedef struct { /* the next states of a step, in order of first arrival (ActivityFilter._add) */
    Py_ssize_t n, cap, tcap, pcap, ccap, acap;
    double *sum, *top;
    Py_ssize_t *parent, *child;
    int32_t *act;
} Merged;

typedef struct {
    PyObject_HEAD
    int kind;
    Py_ssize_t order; /* routine: run labels in a key */
    int step_free;    /* routine: the run n-gram part does not depend on the step (no time-of-day prior) */
    PyObject *dist_fn, *child_fn, *stay_fn, *next_fn; /* Python, asked when a memo misses */
    /* activities */
    PyObject *names; /* list: number -> name */
    PyObject *ids;   /* dict: name -> number */
    int32_t *rank;   /* number -> place of its name in sorted order */
    Py_ssize_t rankcap;
    /* keys */
    Py_ssize_t nkeys, keycap;
    PyObject **keyobj; /* number -> the dynamics' key (routine: built when first needed) */
    int32_t *tokens;   /* routine: `order` per key */
    int32_t *ntok;
    int64_t *start;
    int64_t *mark; /* merging a step: mark == stamp where the key has slot `slot` */
    Py_ssize_t *slot;
    int64_t stamp;
    Py_ssize_t *slots; /* routine: open addressing over key numbers (-1: free) */
    Py_ssize_t slotcap;
    int32_t *scratch; /* routine: order + 1 tokens */
    PyObject *keyids; /* opaque: dict key -> number */
    Map children;     /* opaque: (key, step, activity) -> child key */
    /* memos */
    Memo dists; /* (key, step) -> the next activity's distribution */
    Memo nexts; /* routine: (run labels, step or -1) -> next_runs (z: its total) */
    Map stays;  /* routine: (activity, duration, step) -> stay probability (its bits) */
    /* a step's scratch (one step at a time) */
    int busy;
    Grown grown;
    Merged merged;
} Core;

static PyTypeObject CoreType, BeamType, NodeType, ContextsType, EvidenceType;

static Py_ssize_t n_activities(Core *c) { return PyList_GET_SIZE(c->names); }

/* The number of activity `name` (added when new); -1 on error. */
static int32_t activity_id(Core *c, PyObject *name) {
    if (!PyUnicode_Check(name)) {
        PyErr_Format(PyExc_TypeError, "activities must be str, not %.100s", Py_TYPE(name)->tp_name);
        return -1;
    }
    PyObject *number = PyDict_GetItemWithError(c->ids, name);
    if (number != NULL) return (int32_t)stored_number(number, n_activities(c));
    if (PyErr_Occurred()) return -1;
    Py_ssize_t n = n_activities(c);
    if (n >= INT32_MAX / 2) {
        PyErr_SetString(PyExc_OverflowError, "filter core: too many activities");
        return -1;
    }
    if (reserve((void **)&c->rank, &c->rankcap, n + 1, sizeof(int32_t)) < 0) return -1;
    /* its place among the names sorted (str order, as tuples of names compare) */
    int32_t place = 0;
    for (Py_ssize_t i = 0; i < n; i++) {
        int cmp = PyUnicode_Compare(PyList_GET_ITEM(c->names, i), name);
        if (cmp == -1 && PyErr_Occurred()) return -1;
        if (cmp < 0) place++;
    }
    PyObject *num = PyLong_FromSsize_t(n);
    if (num == NULL) return -1;
    int rc = PyDict_SetItem(c->ids, name, num);
    Py_DECREF(num);
    if (rc < 0) return -1;
    if (PyList_Append(c->names, name) < 0) {
        PyDict_DelItem(c->ids, name);
        return -1;
    }
    for (Py_ssize_t i = 0; i < n; i++)
        if (c->rank[i] >= place) c->rank[i]++;
    c->rank[n] = place;
    return (int32_t)n;
}

static int add_key_arrays(Core *c) {
    Py_ssize_t cap = c->keycap;
    if (c->nkeys < cap) return 0;
    Py_ssize_t cap2 = cap ? 2 * cap : 256;
    PyObject **keyobj = PyMem_Realloc(c->keyobj, (size_t)cap2 * sizeof(PyObject *));
    if (keyobj) c->keyobj = keyobj;
    int64_t *start = PyMem_Realloc(c->start, (size_t)cap2 * sizeof(int64_t));
    if (start) c->start = start;
    int32_t *ntok = PyMem_Realloc(c->ntok, (size_t)cap2 * sizeof(int32_t));
    if (ntok) c->ntok = ntok;
    int64_t *mark = PyMem_Realloc(c->mark, (size_t)cap2 * sizeof(int64_t));
    if (mark) c->mark = mark;
    Py_ssize_t *slot = PyMem_Realloc(c->slot, (size_t)cap2 * sizeof(Py_ssize_t));
    if (slot) c->slot = slot;
    int ok = mark && slot;
    if (c->kind == ROUTINE) {
        int32_t *tokens = PyMem_Realloc(c->tokens, (size_t)cap2 * (size_t)c->order * sizeof(int32_t));
        if (tokens) c->tokens = tokens;
        ok = ok && tokens != NULL;
    }
    if (!keyobj || !start || !ntok || !ok) {
        PyErr_NoMemory();
        return -1;
    }
    c->keycap = cap2;
    return 0;
}

static uint64_t tokens_hash(const int32_t *tok, Py_ssize_t n, int64_t start) {
    uint64_t h = hash3(start, n, 0);
    for (Py_ssize_t i = 0; i < n; i++) h = hash3((int64_t)h, tok[i], i + 1);
    return h;
}

static int routine_slots(Core *c) {
    if (2 * (c->nkeys + 1) <= c->slotcap) return 0;
    Py_ssize_t cap = c->slotcap ? 2 * c->slotcap : 512;
    Py_ssize_t *slots = PyMem_Malloc((size_t)cap * sizeof(Py_ssize_t));
    if (slots == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    for (Py_ssize_t i = 0; i < cap; i++) slots[i] = -1;
    for (Py_ssize_t k = 0; k < c->nkeys; k++) {
        size_t i = (size_t)tokens_hash(c->tokens + k * c->order, c->ntok[k], c->start[k]) & (size_t)(cap - 1);
        while (slots[i] != -1) i = (i + 1) & (size_t)(cap - 1);
        slots[i] = k;
    }
    PyMem_Free(c->slots);
    c->slots = slots;
    c->slotcap = cap;
    return 0;
}

/* The number of the routine key (tokens, start), added when new; -1 on error. */
static Py_ssize_t routine_key(Core *c, const int32_t *tok, Py_ssize_t n, int64_t start) {
    if (routine_slots(c) < 0) return -1;
    size_t mask = (size_t)c->slotcap - 1, i = (size_t)tokens_hash(tok, n, start) & mask;
    for (;; i = (i + 1) & mask) {
        Py_ssize_t k = c->slots[i];
        if (k == -1) break;
        if (c->start[k] == start && c->ntok[k] == n && memcmp(c->tokens + k * c->order, tok, (size_t)n * sizeof(int32_t)) == 0)
            return k;
    }
    if (add_key_arrays(c) < 0) return -1;
    Py_ssize_t k = c->nkeys++;
    memcpy(c->tokens + k * c->order, tok, (size_t)n * sizeof(int32_t));
    c->ntok[k] = (int32_t)n;
    c->start[k] = start;
    c->keyobj[k] = NULL;
    c->mark[k] = 0;
    c->slots[i] = k;
    return k;
}

/* The number of the opaque key `obj`, added when new; -1 on error. */
static Py_ssize_t opaque_key(Core *c, PyObject *obj) {
    PyObject *number = PyDict_GetItemWithError(c->keyids, obj);
    if (number != NULL) return stored_number(number, c->nkeys);
    if (PyErr_Occurred() || add_key_arrays(c) < 0) return -1;
    PyObject *num = PyLong_FromSsize_t(c->nkeys);
    if (num == NULL) return -1;
    int rc = PyDict_SetItem(c->keyids, obj, num);
    Py_DECREF(num);
    if (rc < 0) return -1;
    Py_INCREF(obj);
    c->keyobj[c->nkeys] = obj;
    c->mark[c->nkeys] = 0;
    c->start[c->nkeys] = 0;
    c->ntok[c->nkeys] = 0;
    return c->nkeys++;
}

/* The dynamics' key object of key number k (borrowed); NULL on error. */
static PyObject *key_object(Core *c, Py_ssize_t k) {
    if (c->keyobj[k] != NULL) return c->keyobj[k];
    PyObject *tokens = PyTuple_New(c->ntok[k]);
    if (tokens == NULL) return NULL;
    for (Py_ssize_t i = 0; i < c->ntok[k]; i++) {
        PyObject *name = PyList_GET_ITEM(c->names, c->tokens[k * c->order + i]);
        Py_INCREF(name);
        PyTuple_SET_ITEM(tokens, i, name);
    }
    c->keyobj[k] = Py_BuildValue("(NL)", tokens, (long long)c->start[k]);
    return c->keyobj[k];
}

/* The key of a history of key `key` and `step` activities followed by activity `act`
 * (_RoutineDynamics.child_key, or the dynamics' child_key for opaque keys); -1 on error. */
static Py_ssize_t child_key(Core *c, PyObject *dyn, Py_ssize_t key, int64_t step, int32_t act) {
    if (c->kind == ROUTINE) {
        const int32_t *tok = c->tokens + key * c->order;
        Py_ssize_t n = c->ntok[key];
        if (c->start[key] >= 0 && tok[n - 1] == act) return key; /* the current run goes on */
        memcpy(c->scratch, tok, (size_t)n * sizeof(int32_t));
        c->scratch[n] = act;
        Py_ssize_t keep = n + 1 < c->order ? n + 1 : c->order;
        return routine_key(c, c->scratch + (n + 1 - keep), keep, step);
    }
    int64_t found;
    if (map_get(&c->children, key, step, act, &found)) return (Py_ssize_t)found;
    PyObject *step_obj = PyLong_FromLongLong(step);
    if (step_obj == NULL) return -1;
    PyObject *child = PyObject_CallFunctionObjArgs(c->child_fn, dyn, c->keyobj[key], step_obj,
                                                   PyList_GET_ITEM(c->names, act), NULL);
    Py_DECREF(step_obj);
    if (child == NULL) return -1;
    Py_ssize_t k = opaque_key(c, child);
    Py_DECREF(child);
    if (k < 0) return -1;
    if (c->children.n >= CHILD_LIMIT) map_clear(&c->children);
    return map_put(&c->children, key, step, act, k) < 0 ? -1 : k;
}

static int core_init(Core *self, PyObject *args, PyObject *kwds) {
    int kind, step_free = 0;
    Py_ssize_t order;
    PyObject *dist_fn, *child_fn, *stay_fn = Py_None, *next_fn = Py_None;
    if (!PyArg_ParseTuple(args, "inOO|OOp:Core", &kind, &order, &dist_fn, &child_fn, &stay_fn, &next_fn, &step_free))
        return -1;
    if (self->names != NULL) {
        PyErr_SetString(PyExc_TypeError, "Core: already initialised");
        return -1;
    }
    if ((kind != ROUTINE && kind != OPAQUE) || (kind == ROUTINE && (order < 1 || order > 10000))) {
        PyErr_SetString(PyExc_ValueError, "Core: kind 0 (routine, 1 <= order <= 10000) or 1 (opaque keys)");
        return -1;
    }
    if (!PyCallable_Check(dist_fn) || !PyCallable_Check(child_fn) ||
        (kind == ROUTINE && (!PyCallable_Check(stay_fn) || !PyCallable_Check(next_fn)))) {
        PyErr_SetString(PyExc_TypeError, "Core: the functions asked on memo misses must be callable");
        return -1;
    }
    self->kind = kind;
    self->order = kind == ROUTINE ? order : 0;
    self->step_free = step_free;
    self->stamp = 1;
    self->dists.limit = self->nexts.limit = DIST_LIMIT;
    self->names = PyList_New(0);
    self->ids = PyDict_New();
    self->keyids = PyDict_New();
    if (!self->names || !self->ids || !self->keyids) return -1;
    if (kind == ROUTINE && (self->scratch = PyMem_Malloc((size_t)(order + 1) * sizeof(int32_t))) == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    PyObject *fns[4] = {dist_fn, child_fn, stay_fn, next_fn}, **slots[4] = {&self->dist_fn, &self->child_fn, &self->stay_fn,
                                                                            &self->next_fn};
    for (int i = 0; i < 4; i++) {
        Py_INCREF(fns[i]);
        *slots[i] = fns[i];
    }
    return 0;
}

static void core_dealloc(Core *self) {
    for (Py_ssize_t k = 0; k < self->nkeys; k++) Py_XDECREF(self->keyobj[k]);
    void *arrays[] = {self->keyobj, self->tokens, self->ntok, self->start, self->mark, self->slot, self->slots,
                      self->scratch, self->rank, self->grown.w, self->grown.parent, self->grown.act, self->merged.sum,
                      self->merged.top, self->merged.parent, self->merged.child, self->merged.act};
    for (size_t i = 0; i < sizeof(arrays) / sizeof(arrays[0]); i++) PyMem_Free(arrays[i]);
    map_free(&self->children);
    map_free(&self->stays);
    memo_free(&self->dists);
    memo_free(&self->nexts);
    Py_XDECREF(self->names);
    Py_XDECREF(self->ids);
    Py_XDECREF(self->keyids);
    Py_XDECREF(self->dist_fn);
    Py_XDECREF(self->child_fn);
    Py_XDECREF(self->stay_fn);
    Py_XDECREF(self->next_fn);
    Py_TYPE(self)->tp_free((PyObject *)self);
}

static int core_ready(Core *c) {
    if (c->names == NULL) {
        PyErr_SetString(PyExc_TypeError, "Core: not initialised");
        return -1;
    }
    return 0;
}

/* -- Node: one history (its last activity and its parent) ---------------------------------------- */

typedef struct Node {
    PyObject_HEAD
    struct Node *parent; /* NULL at the day start */
    PyObject *cursor;    /* the dynamics' cursor of this history (NULL until built) */
    Py_ssize_t depth;    /* activities in the history */
    int32_t act;         /* its last activity (-1 at the day start) */
} Node;

static Node *node_new(Node *parent, int32_t act, PyObject *cursor) {
    Node *n = PyObject_New(Node, &NodeType);
    if (n == NULL) return NULL;
    Py_XINCREF(parent);
    n->parent = parent;
    Py_XINCREF(cursor);
    n->cursor = cursor;
    n->depth = parent ? parent->depth + 1 : 0;
    n->act = act;
    return n;
}

static void node_dealloc(Node *self) {
    Node *p = self->parent;
    Py_XDECREF(self->cursor);
    PyObject_Free(self);
    /* a long history is freed in a loop, not by recursion */
    while (p != NULL && Py_REFCNT(p) == 1) {
        Node *next = p->parent;
        p->parent = NULL;
        Py_DECREF(p);
        p = next;
    }
    Py_XDECREF(p);
}

/* The cursor of `node` (borrowed), built from its nearest ancestor that has one by the dynamics'
 * advance(cursor, step, activity), each one kept; NULL on error. */
static PyObject *node_cursor(Core *c, Node *node, PyObject *dyn) {
    if (node->cursor != NULL) return node->cursor;
    Py_ssize_t n = 0;
    for (Node *p = node; p != NULL && p->cursor == NULL; p = p->parent) n++;
    Node **path = PyMem_Malloc((size_t)n * sizeof(Node *));
    if (path == NULL) {
        PyErr_NoMemory();
        return NULL;
    }
    Node *p = node;
    for (Py_ssize_t i = n - 1; i >= 0; i--, p = p->parent) path[i] = p;
    if (p == NULL) {
        PyMem_Free(path);
        PyErr_SetString(PyExc_RuntimeError, "filter core: a history without a start");
        return NULL;
    }
    for (Py_ssize_t i = 0; i < n; i++) {
        Node *q = path[i];
        if (q->act < 0 || q->act >= n_activities(c)) {
            PyMem_Free(path);
            PyErr_SetString(PyExc_RuntimeError, "filter core: a history's activity is out of range");
            return NULL;
        }
        PyObject *step = PyLong_FromSsize_t(q->parent->depth);
        if (step == NULL) {
            PyMem_Free(path);
            return NULL;
        }
        q->cursor = PyObject_CallMethodObjArgs(dyn, s_advance, q->parent->cursor, step, PyList_GET_ITEM(c->names, q->act), NULL);
        Py_DECREF(step);
        if (q->cursor == NULL) {
            PyMem_Free(path);
            return NULL;
        }
    }
    PyMem_Free(path);
    return node->cursor;
}

/* The history of `node` as a tuple of names (new reference). */
static PyObject *node_history(Core *c, Node *node) {
    PyObject *out = PyTuple_New(node->depth);
    if (out == NULL) return NULL;
    Py_ssize_t i = node->depth;
    for (Node *p = node; p != NULL && i > 0; p = p->parent) {
        if (p->act < 0 || p->act >= n_activities(c)) {
            Py_DECREF(out);
            PyErr_SetString(PyExc_RuntimeError, "filter core: a history's activity is out of range");
            return NULL;
        }
        PyObject *name = PyList_GET_ITEM(c->names, p->act);
        Py_INCREF(name);
        PyTuple_SET_ITEM(out, --i, name);
    }
    return out;
}

/* -- Beam: the weighted histories kept after a step ------------------------------------------------ */

typedef struct {
    PyObject_HEAD
    Core *core;
    Py_ssize_t depth; /* activities in every kept history */
    Py_ssize_t n;
    double *weight;
    Py_ssize_t *key;
    int32_t *rank; /* the history's place among these histories sorted (equal histories: equal) */
    Node **node;
} Beam;

static Beam *beam_new(Core *c, Py_ssize_t depth, Py_ssize_t n) {
    Beam *b = PyObject_New(Beam, &BeamType);
    if (b == NULL) return NULL;
    Py_INCREF(c);
    b->core = c;
    b->depth = depth;
    b->n = 0; /* entries filled so far (all freed on error) */
    b->weight = PyMem_Malloc((size_t)n * sizeof(double));
    b->key = PyMem_Malloc((size_t)n * sizeof(Py_ssize_t));
    b->rank = PyMem_Malloc((size_t)n * sizeof(int32_t));
    b->node = PyMem_Malloc((size_t)n * sizeof(Node *));
    if (!b->weight || !b->key || !b->rank || !b->node) {
        Py_DECREF(b);
        PyErr_NoMemory();
        return NULL;
    }
    return b;
}

static void beam_dealloc(Beam *self) {
    if (self->node != NULL)
        for (Py_ssize_t i = 0; i < self->n; i++) Py_XDECREF(self->node[i]);
    PyMem_Free(self->weight);
    PyMem_Free(self->key);
    PyMem_Free(self->rank);
    PyMem_Free(self->node);
    Py_XDECREF(self->core);
    PyObject_Free(self);
}

/* A next-activity distribution: `n` activities and their probabilities, in the dict's order. */
typedef struct {
    const int32_t *act;
    const double *p;
    Py_ssize_t n;
    int32_t one_act; /* the "stays the same" distribution of a model with nothing to say */
    double one_p;
} Dist;

/* Add the items of `dist` (a dict: activity -> probability, in its order) to `t`. */
static int items_from_dict(Core *c, Items *t, PyObject *dist) {
    if (!PyDict_Check(dist)) {
        PyErr_Format(PyExc_TypeError, "a distribution must be a dict, not %.100s", Py_TYPE(dist)->tp_name);
        return -1;
    }
    Py_ssize_t n = PyDict_GET_SIZE(dist), pos = 0, end = t->n + n;
    if (items_reserve(t, end) < 0) return -1;
    PyObject *name, *value;
    while (t->n < end && PyDict_Next(dist, &pos, &name, &value)) {
        Py_INCREF(name);
        Py_INCREF(value);
        int32_t a = activity_id(c, name);
        double p = a < 0 ? -1.0 : PyFloat_AsDouble(value);
        Py_DECREF(name);
        Py_DECREF(value);
        if (a < 0 || (p == -1.0 && PyErr_Occurred())) return -1;
        t->act[t->n] = a;
        t->p[t->n++] = p;
    }
    return 0;
}

/* The distribution of entry i of `b` asked from Python: dist_fn(dyn, key, step, beam, i). */
static Py_ssize_t asked_dist(Beam *b, PyObject *dyn, Py_ssize_t i) {
    Core *c = b->core;
    PyObject *key = key_object(c, b->key[i]);
    if (key == NULL) return -1;
    PyObject *step = PyLong_FromSsize_t(b->depth), *index = PyLong_FromSsize_t(i);
    PyObject *dist = step && index ? PyObject_CallFunctionObjArgs(c->dist_fn, dyn, key, step, (PyObject *)b, index, NULL) : NULL;
    Py_XDECREF(step);
    Py_XDECREF(index);
    if (dist == NULL) return -1;
    Py_ssize_t first, out = -1;
    if (memo_open(&c->dists, PyDict_Check(dist) ? PyDict_GET_SIZE(dist) : 0) == 0) {
        first = c->dists.items.n;
        if (items_from_dict(c, &c->dists.items, dist) == 0) out = memo_close(&c->dists, first, 0.0, b->key[i], b->depth, 0);
    }
    Py_DECREF(dist);
    return out;
}

/* _RoutineDynamics.stay(activity number a, duration, step), remembered. */
static int routine_stay(Core *c, PyObject *dyn, int32_t a, int64_t duration, int64_t step, double *out) {
    int64_t bits;
    if (map_get(&c->stays, a, duration, step, &bits)) {
        memcpy(out, &bits, sizeof(double));
        return 0;
    }
    PyObject *d = PyLong_FromLongLong(duration), *s = PyLong_FromLongLong(step);
    PyObject *r = d && s ? PyObject_CallFunctionObjArgs(c->stay_fn, dyn, PyList_GET_ITEM(c->names, a), d, s, NULL) : NULL;
    Py_XDECREF(d);
    Py_XDECREF(s);
    if (r == NULL) return -1;
    double v = PyFloat_AsDouble(r);
    Py_DECREF(r);
    if (v == -1.0 && PyErr_Occurred()) return -1;
    if (c->stays.n >= STAY_LIMIT) map_clear(&c->stays);
    memcpy(&bits, &v, sizeof(double));
    if (map_put(&c->stays, a, duration, step, bits) < 0) return -1;
    *out = v;
    return 0;
}

/* _RoutineDynamics.next_runs of the run labels `t` (a TOKENS_ONLY key) at `step`, remembered: asked
 * with next_fn(dyn, step, beam, i) (entry i of `b` has these run labels). */
static Py_ssize_t routine_next(Beam *b, PyObject *dyn, Py_ssize_t i, Py_ssize_t t) {
    Core *c = b->core;
    int64_t at = c->step_free ? -1 : b->depth;
    Py_ssize_t found;
    if (memo_get(&c->nexts, t, at, 0, &found)) return found;
    PyObject *step = PyLong_FromSsize_t(b->depth), *index = PyLong_FromSsize_t(i);
    PyObject *r = step && index ? PyObject_CallFunctionObjArgs(c->next_fn, dyn, step, (PyObject *)b, index, NULL) : NULL;
    Py_XDECREF(step);
    Py_XDECREF(index);
    if (r == NULL) return -1;
    Py_ssize_t out = -1;
    if (!PyTuple_Check(r) || PyTuple_GET_SIZE(r) != 2) {
        PyErr_SetString(PyExc_TypeError, "next_runs must give (a dict, its total)");
    } else {
        PyObject *nxt = PyTuple_GET_ITEM(r, 0);
        double z = PyFloat_AsDouble(PyTuple_GET_ITEM(r, 1));
        if (!(z == -1.0 && PyErr_Occurred()) && memo_open(&c->nexts, PyDict_Check(nxt) ? PyDict_GET_SIZE(nxt) : 0) == 0) {
            Py_ssize_t first = c->nexts.items.n;
            if (items_from_dict(c, &c->nexts.items, nxt) == 0) out = memo_close(&c->nexts, first, z, t, at, 0);
        }
    }
    Py_DECREF(r);
    return out;
}

/* The distribution of routine entry i of `b` (its current run began at step >= 0): the stay
 * probability and the next run's activity, mixed as _RoutineDynamics._compute does. */
static Py_ssize_t routine_dist(Beam *b, PyObject *dyn, Py_ssize_t i) {
    Core *c = b->core;
    Py_ssize_t k = b->key[i], n = c->ntok[k];
    int64_t step = b->depth, start = c->start[k];
    if (n < 1 || start > step) {
        PyErr_SetString(PyExc_RuntimeError, "filter core: a routine key out of range");
        return -1;
    }
    int32_t current = c->tokens[k * c->order + n - 1];
    double stay;
    if (routine_stay(c, dyn, current, step - start, step, &stay) < 0) return -1;
    memcpy(c->scratch, c->tokens + k * c->order, (size_t)n * sizeof(int32_t)); /* (routine_key may move tokens) */
    Py_ssize_t t = routine_key(c, c->scratch, n, TOKENS_ONLY);
    Py_ssize_t j = t < 0 ? -1 : routine_next(b, dyn, i, t);
    if (j < 0) return -1;
    Py_ssize_t len = c->nexts.spans.len[j];
    if (memo_open(&c->dists, len + 1) < 0) return -1;
    const Items *nx = &c->nexts.items;
    Items *out = &c->dists.items;
    Py_ssize_t first = out->n, from = c->nexts.spans.first[j];
    double z = c->nexts.spans.z[j];
    if (z > 0)
        for (Py_ssize_t m = 0; m < len; m++, out->n++) {
            out->act[out->n] = nx->act[from + m];
            out->p[out->n] = (1.0 - stay) * nx->p[from + m] / z;
        }
    out->act[out->n] = current;
    out->p[out->n++] = z > 0 ? stay : 1.0;
    return memo_close(&c->dists, first, 0.0, k, step, 0);
}

/* The distribution of entry i of `b` (ActivityFilter._next), remembered by (key, step). Valid
 * until the next call. */
static int next_of(Beam *b, PyObject *dyn, Py_ssize_t i, Dist *d) {
    Core *c = b->core;
    Py_ssize_t found;
    if (!memo_get(&c->dists, b->key[i], b->depth, 0, &found)) {
        found = c->kind == ROUTINE && c->start[b->key[i]] >= 0 ? routine_dist(b, dyn, i) : asked_dist(b, dyn, i);
        if (found < 0) return -1;
    }
    const Spans *s = &c->dists.spans;
    d->act = c->dists.items.act + s->first[found];
    d->p = c->dists.items.p + s->first[found];
    d->n = s->len[found];
    if (d->n == 0 && b->depth > 0) { /* a model with nothing to say: the activity stays the same */
        d->one_act = b->node[i]->act;
        d->one_p = 1.0;
        d->act = &d->one_act;
        d->p = &d->one_p;
        d->n = 1;
    }
    return 0;
}

/* -- Contexts and Evidence: MovementEmission's likelihoods ---------------------------------------- */

typedef struct {
    PyObject_HEAD
    Core *core;
    PyObject *objects; /* dict: object name -> number (the emission's object columns) */
    PyObject *object_names; /* tuple: number -> name */
    Py_ssize_t nobj;
    PyObject *nothing_fn, *odds_fn; /* Python: (emission, part, activity, changed, following[, object]) -> float */
    Map index; /* (3 * part + flag, activity, following + 1) -> context */
    Py_ssize_t n, cap;
    int32_t *part, *act, *flag, *following;
    double *nothing;
    uint8_t *has_nothing;
    double *odds; /* cap * nobj */
    uint8_t *has_odds;
} Contexts;

static Py_ssize_t context_of(Contexts *x, int part, int32_t act, int flag, int32_t following) {
    int64_t found;
    if (map_get(&x->index, 3 * part + flag, act, following + 1, &found)) return (Py_ssize_t)found;
    if (x->n == x->cap) {
        Py_ssize_t cap = x->cap ? 2 * x->cap : 64;
        int32_t *a = PyMem_Realloc(x->part, (size_t)cap * sizeof(int32_t));
        if (a) x->part = a;
        int32_t *b = PyMem_Realloc(x->act, (size_t)cap * sizeof(int32_t));
        if (b) x->act = b;
        int32_t *f = PyMem_Realloc(x->flag, (size_t)cap * sizeof(int32_t));
        if (f) x->flag = f;
        int32_t *g = PyMem_Realloc(x->following, (size_t)cap * sizeof(int32_t));
        if (g) x->following = g;
        double *no = PyMem_Realloc(x->nothing, (size_t)cap * sizeof(double));
        if (no) x->nothing = no;
        uint8_t *hn = PyMem_Realloc(x->has_nothing, (size_t)cap);
        if (hn) x->has_nothing = hn;
        size_t width = x->nobj ? (size_t)x->nobj : 1;
        double *od = PyMem_Realloc(x->odds, (size_t)cap * width * sizeof(double));
        if (od) x->odds = od;
        uint8_t *ho = PyMem_Realloc(x->has_odds, (size_t)cap * width);
        if (ho) x->has_odds = ho;
        if (!a || !b || !f || !g || !no || !hn || !od || !ho) {
            PyErr_NoMemory();
            return -1;
        }
        x->cap = cap;
    }
    Py_ssize_t k = x->n;
    x->part[k] = part;
    x->act[k] = act;
    x->flag[k] = flag;
    x->following[k] = following;
    x->has_nothing[k] = 0;
    if (x->nobj) memset(x->has_odds + k * x->nobj, 0, (size_t)x->nobj);
    if (map_put(&x->index, 3 * part + flag, act, following + 1, k) < 0) return -1;
    return x->n++;
}

/* Calls fn(emission, part, activity, changed, following[, object]) of context k; a float. */
static int context_call(Contexts *x, PyObject *fn, PyObject *em, Py_ssize_t k, PyObject *obj, double *out) {
    Core *c = x->core;
    if (x->act[k] < 0 || x->act[k] >= n_activities(c) || x->following[k] >= n_activities(c)) {
        PyErr_SetString(PyExc_RuntimeError, "filter core: a context's activity is out of range");
        return -1;
    }
    PyObject *part = PyLong_FromLong(x->part[k]);
    if (part == NULL) return -1;
    PyObject *changed = x->flag[k] == FLAG_NONE ? Py_None : (x->flag[k] == FLAG_TRUE ? Py_True : Py_False);
    PyObject *following = x->following[k] < 0 ? Py_None : PyList_GET_ITEM(c->names, x->following[k]);
    PyObject *r = PyObject_CallFunctionObjArgs(fn, em, part, PyList_GET_ITEM(c->names, x->act[k]), changed, following, obj, NULL);
    Py_DECREF(part);
    if (r == NULL) return -1;
    double v = PyFloat_AsDouble(r);
    Py_DECREF(r);
    if (v == -1.0 && PyErr_Occurred()) return -1;
    *out = v;
    return 0;
}

/* log P(exactly the objects `obj` moved | context k), untempered (part_log_likelihood). */
static int part_log_likelihood(Contexts *x, PyObject *em, Py_ssize_t k, const Py_ssize_t *obj, Py_ssize_t nobj, double *out) {
    if (!x->has_nothing[k]) {
        double v;
        if (context_call(x, x->nothing_fn, em, k, NULL, &v) < 0) return -1;
        x->nothing[k] = v;
        x->has_nothing[k] = 1;
    }
    double ll = x->nothing[k];
    for (Py_ssize_t i = 0; i < nobj; i++) {
        Py_ssize_t at = k * x->nobj + obj[i];
        if (!x->has_odds[at]) {
            double v;
            if (context_call(x, x->odds_fn, em, k, PyTuple_GET_ITEM(x->object_names, obj[i]), &v) < 0) return -1;
            x->odds[at] = v;
            x->has_odds[at] = 1;
        }
        ll += x->odds[at];
    }
    *out = ll;
    return 0;
}

static void contexts_dealloc(Contexts *self) {
    map_free(&self->index);
    PyMem_Free(self->part);
    PyMem_Free(self->act);
    PyMem_Free(self->flag);
    PyMem_Free(self->following);
    PyMem_Free(self->nothing);
    PyMem_Free(self->has_nothing);
    PyMem_Free(self->odds);
    PyMem_Free(self->has_odds);
    Py_XDECREF(self->core);
    Py_XDECREF(self->objects);
    Py_XDECREF(self->object_names);
    Py_XDECREF(self->nothing_fn);
    Py_XDECREF(self->odds_fn);
    PyObject_Free(self);
}

typedef struct {
    Py_ssize_t *obj; /* the moved objects the emission knows, in the set's order */
    Py_ssize_t nobj;
    double top;       /* the upper bound */
    Py_ssize_t width; /* activities per row */
    double *rows;     /* (width + 1) rows by previous activity (the last: none) of `width`; -1: not yet */
} Moved;

typedef struct {
    PyObject_HEAD
    Core *core;
    Contexts *contexts;
    double weight, lam, log_lam, log1m_lam, log1m_zero;
    int boundary, switch_;
    uint8_t *bounded; /* activity number -> its evidence is at most 1 (the upper bound covers it) */
    Py_ssize_t nbounded;
    Map switches; /* (a, b): the switch a -> b was seen */
    Py_ssize_t *upper; /* the contexts of the upper bound, in MovementEmission.upper_bound's order */
    Py_ssize_t nupper;
    PyObject *moved; /* dict: moved set -> number */
    Moved *entries;
    Py_ssize_t nentries, entrycap;
} Evidence;

static void moved_free(Moved *m) {
    PyMem_Free(m->obj);
    PyMem_Free(m->rows);
}

static void evidence_dealloc(Evidence *self) {
    for (Py_ssize_t i = 0; i < self->nentries; i++) moved_free(&self->entries[i]);
    PyMem_Free(self->entries);
    PyMem_Free(self->bounded);
    PyMem_Free(self->upper);
    map_free(&self->switches);
    Py_XDECREF(self->moved);
    Py_XDECREF(self->contexts);
    Py_XDECREF(self->core);
    PyObject_Free(self);
}

static int is_bounded(Evidence *e, int32_t a) { return a >= 0 && a < e->nbounded && e->bounded[a]; }

/* weight * log P(moved | previous activity prev (-1: none), current activity cur): log_likelihood. */
static int log_likelihood(Evidence *e, PyObject *em, const Moved *m, int32_t prev, int32_t cur, double *out) {
    Contexts *x = e->contexts;
    double parts[2], v;
    int n = 0;
    if (prev < 0) { /* no previous activity: all of it is credited to the current one */
        Py_ssize_t k = context_of(x, 1, cur, FLAG_NONE, -1);
        if (k < 0 || part_log_likelihood(x, em, k, m->obj, m->nobj, &v) < 0) return -1;
        parts[n++] = e->log1m_zero + v;
    } else {
        int flag = e->boundary ? (prev != cur ? FLAG_TRUE : FLAG_FALSE) : FLAG_NONE;
        if (e->lam > 0.0) {
            int64_t seen;
            int32_t following = flag == FLAG_TRUE && e->switch_ && map_get(&e->switches, prev, cur, 0, &seen) ? cur : -1;
            Py_ssize_t k = context_of(x, 0, prev, flag, following);
            if (k < 0 || part_log_likelihood(x, em, k, m->obj, m->nobj, &v) < 0) return -1;
            parts[n++] = e->log_lam + v;
        }
        if (e->lam < 1.0) {
            Py_ssize_t k = context_of(x, 1, cur, flag, -1);
            if (k < 0 || part_log_likelihood(x, em, k, m->obj, m->nobj, &v) < 0) return -1;
            parts[n++] = e->log1m_lam + v;
        }
    }
    if (n == 0) {
        PyErr_SetString(PyExc_ValueError, "max() arg is an empty sequence");
        return -1;
    }
    double top = parts[0];
    if (n > 1 && parts[1] > top) top = parts[1];
    double terms[2];
    for (int i = 0; i < n; i++) terms[i] = exp(parts[i] - top);
    double inner = top + log(float_sum(terms, n));
    *out = e->weight * inner;
    return 0;
}

/* The number of the entry of the set `moved` (made on first use: its objects and upper bound). */
static Py_ssize_t moved_entry(Evidence *e, PyObject *em, PyObject *moved) {
    PyObject *number = PyDict_GetItemWithError(e->moved, moved);
    if (number != NULL) return stored_number(number, e->nentries);
    if (PyErr_Occurred()) return -1;
    if (e->nentries >= MOVED_LIMIT) { /* start over, as MovementEmission.evidence does */
        for (Py_ssize_t i = 0; i < e->nentries; i++) moved_free(&e->entries[i]);
        e->nentries = 0;
        PyDict_Clear(e->moved);
    }
    if (reserve((void **)&e->entries, &e->entrycap, e->nentries + 1, sizeof(Moved)) < 0) return -1;
    Moved m;
    memset(&m, 0, sizeof(m));
    Py_ssize_t size = PySet_GET_SIZE(moved);
    m.obj = PyMem_Malloc((size_t)(size ? size : 1) * sizeof(Py_ssize_t));
    /* in name order, as `for o in sorted(moved)`: a set's own order follows the process's hash
       seed, and the sum of the objects' terms would too */
    PyObject *names = PySequence_List(moved), *it = NULL, *item;
    if (names != NULL && PyList_Sort(names) == 0) it = PyObject_GetIter(names);
    Py_XDECREF(names);
    if (m.obj == NULL || it == NULL) {
        Py_XDECREF(it);
        moved_free(&m);
        if (!PyErr_Occurred()) PyErr_NoMemory();
        return -1;
    }
    while ((item = PyIter_Next(it)) != NULL) {
        PyObject *o = PyDict_GetItemWithError(e->contexts->objects, item);
        Py_DECREF(item);
        if (o == NULL && PyErr_Occurred()) break;
        if (o == NULL) continue; /* unknown to training: no evidence */
        Py_ssize_t j = stored_number(o, e->contexts->nobj);
        if (j < 0) break;
        if (m.nobj >= size) {
            PyErr_SetString(PyExc_RuntimeError, "filter core: the moved set changed while read");
            break;
        }
        m.obj[m.nobj++] = j;
    }
    Py_DECREF(it);
    if (PyErr_Occurred()) {
        moved_free(&m);
        return -1;
    }
    double best = 0.0;
    for (Py_ssize_t i = 0; i < e->nupper; i++) {
        double v;
        if (part_log_likelihood(e->contexts, em, e->upper[i], m.obj, m.nobj, &v) < 0) {
            moved_free(&m);
            return -1;
        }
        if (i == 0 || v > best) best = v;
    }
    m.top = e->weight * best;
    PyObject *num = PyLong_FromSsize_t(e->nentries);
    if (num == NULL || PyDict_SetItem(e->moved, moved, num) < 0) {
        Py_XDECREF(num);
        moved_free(&m);
        return -1;
    }
    Py_DECREF(num);
    e->entries[e->nentries] = m;
    return e->nentries++;
}

/* exp(log_likelihood(prev, cur) - top) of moved set entry mi, remembered. */
static int row_value(Evidence *e, PyObject *em, Py_ssize_t mi, int32_t prev, int32_t cur, double *out) {
    Moved *m = &e->entries[mi];
    Py_ssize_t need = (prev > cur ? prev : cur) + 1;
    if (need > m->width) {
        Py_ssize_t width = n_activities(e->core) > need ? n_activities(e->core) : need;
        double *rows = PyMem_Malloc((size_t)(width + 1) * (size_t)width * sizeof(double));
        if (rows == NULL) {
            PyErr_NoMemory();
            return -1;
        }
        for (Py_ssize_t i = 0; i < (width + 1) * width; i++) rows[i] = -1.0;
        for (Py_ssize_t r = 0; r <= m->width; r++) {
            Py_ssize_t to = r == m->width ? width : r;
            if (m->width) memcpy(rows + to * width, m->rows + r * m->width, (size_t)m->width * sizeof(double));
        }
        PyMem_Free(m->rows);
        m->rows = rows;
        m->width = width;
    }
    Py_ssize_t at = (prev < 0 ? m->width : prev) * m->width + cur;
    if (m->rows[at] >= 0.0) {
        *out = m->rows[at];
        return 0;
    }
    double ll;
    if (log_likelihood(e, em, m, prev, cur, &ll) < 0) return -1;
    m->rows[at] = exp(ll - m->top);
    *out = m->rows[at];
    return 0;
}

/* -- the step ------------------------------------------------------------------------------------ */

static int grown_push(Grown *g, double w, Py_ssize_t parent, int32_t act) {
    if (reserve((void **)&g->w, &g->cap, g->n + 1, sizeof(double)) < 0 ||
        reserve((void **)&g->parent, &g->pcap, g->n + 1, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&g->act, &g->acap, g->n + 1, sizeof(int32_t)) < 0)
        return -1;
    g->w[g->n] = w;
    g->parent[g->n] = parent;
    g->act[g->n] = act;
    g->n++;
    return 0;
}

/* Merge the extension of entry `parent` of `b` by `act` (weight w) into its next state: the most
 * probable member represents it, the first among equals (ActivityFilter._add). */
static int merge(Beam *b, PyObject *dyn, Py_ssize_t parent, int32_t act, double w) {
    Core *c = b->core;
    Merged *m = &c->merged;
    Py_ssize_t child = child_key(c, dyn, b->key[parent], b->depth, act);
    if (child < 0) return -1;
    if (c->mark[child] == c->stamp) {
        Py_ssize_t s = c->slot[child];
        m->sum[s] += w;
        if (w > m->top[s]) {
            m->parent[s] = parent;
            m->act[s] = act;
            m->top[s] = w;
        }
        return 0;
    }
    if (reserve((void **)&m->sum, &m->cap, m->n + 1, sizeof(double)) < 0 ||
        reserve((void **)&m->top, &m->tcap, m->n + 1, sizeof(double)) < 0 ||
        reserve((void **)&m->parent, &m->pcap, m->n + 1, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&m->child, &m->ccap, m->n + 1, sizeof(Py_ssize_t)) < 0 ||
        reserve((void **)&m->act, &m->acap, m->n + 1, sizeof(int32_t)) < 0)
        return -1;
    c->mark[child] = c->stamp;
    c->slot[child] = m->n;
    m->sum[m->n] = w;
    m->top[m->n] = w;
    m->parent[m->n] = parent;
    m->child[m->n] = child;
    m->act[m->n] = act;
    m->n++;
    return 0;
}

typedef struct {
    const Merged *m;
    const Beam *b;
    const int32_t *rank; /* activity number -> place in sorted order */
} SlotOrder;

/* The sort of ActivityFilter._advance: by -weight, then the representative's history (its
 * parent's, all as long, then its activity). */
static int slot_before(const void *ctx, Py_ssize_t x, Py_ssize_t y) {
    const SlotOrder *o = ctx;
    double wx = -o->m->sum[x], wy = -o->m->sum[y];
    if (wx != wy) return wx < wy;
    int32_t rx = o->b->rank[o->m->parent[x]], ry = o->b->rank[o->m->parent[y]];
    if (rx != ry) return rx < ry;
    return o->rank[o->m->act[x]] < o->rank[o->m->act[y]];
}

typedef struct {
    const int32_t *parent_rank, *act_rank; /* per new entry */
} HistoryOrder;

static int history_before(const void *ctx, Py_ssize_t x, Py_ssize_t y) {
    const HistoryOrder *o = ctx;
    if (o->parent_rank[x] != o->parent_rank[y]) return o->parent_rank[x] < o->parent_rank[y];
    return o->act_rank[x] < o->act_rank[y];
}

/* The first loop of ActivityFilter._advance: every extension worth scoring, with its weight. */
static int score(Beam *b, PyObject *dyn, int32_t label, Evidence *ev, Py_ssize_t mi, PyObject *em, double min_weight,
                 Grown *g, double *best_out) {
    double best = 0.0;
    for (Py_ssize_t i = 0; i < b->n; i++) {
        Dist d;
        if (next_of(b, dyn, i, &d) < 0) return -1;
        if (label >= 0) { /* a visible label: only its extension */
            double p = 0.0;
            for (Py_ssize_t k = 0; k < d.n; k++)
                if (d.act[k] == label) {
                    p = d.p[k];
                    break;
                }
            d.one_act = label;
            d.one_p = p;
            d.act = &d.one_act;
            d.p = &d.one_p;
            d.n = 1;
        }
        int32_t prev = b->depth > 0 ? b->node[i]->act : -1;
        int prev_bounded = 1, any_bounded = 1;
        if (ev != NULL) {
            prev_bounded = prev < 0 || is_bounded(ev, prev);
            any_bounded = 0;
        }
        double hw = b->weight[i];
        for (Py_ssize_t k = 0; k < d.n; k++) {
            int32_t a = d.act[k];
            double w = hw * d.p[k];
            /* below min_weight of the best so far and evidence <= 1: cannot reach the floor */
            double bar = min_weight * best;
            if (w < bar && prev_bounded && (any_bounded || is_bounded(ev, a))) continue;
            if (w > 0.0 && ev != NULL) {
                double r;
                if (row_value(ev, em, mi, prev, a, &r) < 0) return -1;
                w *= r;
            }
            if (w > 0.0) {
                if (grown_push(g, w, i, a) < 0) return -1;
                if (w > best) best = w;
            }
        }
    }
    *best_out = best;
    return 0;
}

/* Nothing kept: the label (or movement) is impossible under the model. The evidence wins over
 * the model: keep the histories' weights and extend them as observed (or by their best guess). */
static int fall_back(Beam *b, PyObject *dyn, int32_t label) {
    for (Py_ssize_t i = 0; i < b->n; i++) {
        Dist d;
        if (next_of(b, dyn, i, &d) < 0) return -1;
        int32_t guess = b->depth > 0 ? b->node[i]->act : -1;
        if (d.n > 0) {
            Py_ssize_t top = 0;
            for (Py_ssize_t k = 1; k < d.n; k++)
                if (d.p[k] > d.p[top]) top = k;
            guess = d.act[top];
        }
        int32_t chosen = label >= 0 ? label : guess;
        if (chosen >= 0 && merge(b, dyn, i, chosen, b->weight[i]) < 0) return -1;
    }
    return 0;
}

/* The next beam from the merged states: the most probable max_h, those below min_weight of
 * their total dropped (the first one always kept), renormalised. */
static Beam *next_beam(Beam *b, Merged *m, double min_weight, Py_ssize_t max_h) {
    Core *c = b->core;
    Beam *out = NULL;
    Py_ssize_t n = m->n;
    Py_ssize_t *order = PyMem_Malloc((size_t)n * sizeof(Py_ssize_t)), *tmp = PyMem_Malloc((size_t)n * sizeof(Py_ssize_t));
    double *w = PyMem_Malloc((size_t)n * sizeof(double));
    int32_t *prank = PyMem_Malloc((size_t)n * sizeof(int32_t)), *arank = PyMem_Malloc((size_t)n * sizeof(int32_t));
    Py_ssize_t *keep = PyMem_Malloc((size_t)n * sizeof(Py_ssize_t)), *hist = PyMem_Malloc((size_t)n * sizeof(Py_ssize_t));
    if (!order || !tmp || !w || !prank || !arank || !keep || !hist) {
        PyErr_NoMemory();
        goto done;
    }
    for (Py_ssize_t s = 0; s < n; s++) order[s] = s;
    SlotOrder so = {m, b, c->rank};
    sort_indices(order, tmp, n, slot_before, &so);
    Py_ssize_t k = n < max_h ? n : max_h;
    for (Py_ssize_t j = 0; j < k; j++) w[j] = m->sum[order[j]];
    double total = float_sum(w, k), floor = min_weight * total;
    Py_ssize_t kept = 0;
    for (Py_ssize_t j = 0; j < k; j++)
        if (m->sum[order[j]] >= floor) keep[kept++] = order[j];
    if (kept == 0) keep[kept++] = order[0];
    for (Py_ssize_t j = 0; j < kept; j++) w[j] = m->sum[keep[j]];
    total = float_sum(w, kept);
    out = beam_new(c, b->depth + 1, kept);
    if (out == NULL) goto done;
    for (Py_ssize_t j = 0; j < kept; j++) {
        Py_ssize_t s = keep[j];
        PyObject *cursor = c->kind == OPAQUE ? c->keyobj[m->child[s]] : NULL; /* an opaque key is its cursor */
        Node *node = node_new(b->node[m->parent[s]], m->act[s], cursor);
        if (node == NULL) {
            Py_CLEAR(out);
            goto done;
        }
        out->node[j] = node;
        out->weight[j] = m->sum[s] / total;
        out->key[j] = m->child[s];
        out->n = j + 1;
        prank[j] = b->rank[m->parent[s]];
        arank[j] = c->rank[m->act[s]];
        hist[j] = j;
    }
    /* each history's place among the new ones: by its parent's place, then its activity */
    HistoryOrder ho = {prank, arank};
    sort_indices(hist, tmp, kept, history_before, &ho);
    for (Py_ssize_t j = 0, r = 0; j < kept; j++) {
        if (j > 0 && history_before(&ho, hist[j - 1], hist[j])) r++;
        out->rank[hist[j]] = (int32_t)r;
    }
done:
    PyMem_Free(order);
    PyMem_Free(tmp);
    PyMem_Free(w);
    PyMem_Free(prank);
    PyMem_Free(arank);
    PyMem_Free(keep);
    PyMem_Free(hist);
    return out;
}

static PyObject *beam_advance(Beam *self, PyObject *args) {
    PyObject *dyn, *label, *evidence, *moved, *em;
    long long step;
    double min_weight;
    Py_ssize_t max_h;
    if (!PyArg_ParseTuple(args, "OLOOOdnO:advance", &dyn, &step, &label, &evidence, &moved, &min_weight, &max_h, &em))
        return NULL;
    Core *c = self->core;
    if (step != self->depth) {
        PyErr_Format(PyExc_ValueError, "advance: step %lld after histories of %zd activities", step, self->depth);
        return NULL;
    }
    if (max_h < 1) {
        PyErr_SetString(PyExc_ValueError, "advance: max_hypotheses must be at least 1");
        return NULL;
    }
    int32_t label_id = -1;
    if (label != Py_None && (label_id = activity_id(c, label)) < 0) return NULL;
    Evidence *ev = NULL;
    Py_ssize_t mi = -1;
    if (evidence != Py_None) {
        if (!PyObject_TypeCheck(evidence, &EvidenceType) || !PyAnySet_Check(moved)) {
            PyErr_SetString(PyExc_TypeError, "advance: evidence must be an Evidence and moved a set");
            return NULL;
        }
        ev = (Evidence *)evidence;
        if (ev->core != c) {
            PyErr_SetString(PyExc_ValueError, "advance: the evidence belongs to another core");
            return NULL;
        }
        if ((mi = moved_entry(ev, em, moved)) < 0) return NULL;
    }
    if (c->busy) {
        PyErr_SetString(PyExc_RuntimeError, "advance: a step of this core is already under way");
        return NULL;
    }
    c->busy = 1;
    c->stamp++;
    Grown *g = &c->grown;
    Merged *m = &c->merged;
    g->n = m->n = 0;
    Beam *out = NULL;
    double best;
    if (score(self, dyn, label_id, ev, mi, em, min_weight, g, &best) < 0) goto done;
    /* extensions far below the best cannot reach min_weight of the total: not merged */
    double floor = min_weight * best;
    for (Py_ssize_t j = 0; j < g->n; j++)
        if (g->w[j] >= floor && merge(self, dyn, g->parent[j], g->act[j], g->w[j]) < 0) goto done;
    if (m->n == 0 && fall_back(self, dyn, label_id) < 0) goto done;
    if (m->n == 0) {
        PyErr_SetString(PyExc_ValueError, "the activity model predicts nothing for the first step; is it fitted?");
        goto done;
    }
    out = next_beam(self, m, min_weight, max_h);
done:
    c->busy = 0;
    return (PyObject *)out;
}

/* -- reading a beam ------------------------------------------------------------------------------ */

typedef struct { /* sums by activity, in order of first arrival (as a dict filled with get(a, 0.0) + x) */
    Py_ssize_t n, cap, acap, vcap;
    Py_ssize_t *at; /* activity number -> position, or -1 */
    int32_t *act;
    double *value;
} Tally;

static int tally_add(Tally *t, int32_t a, double x) {
    if (a >= t->cap) {
        Py_ssize_t old = t->cap;
        if (reserve((void **)&t->at, &t->cap, a + 1, sizeof(Py_ssize_t)) < 0) return -1;
        for (Py_ssize_t i = old; i < t->cap; i++) t->at[i] = -1;
    }
    if (t->at[a] < 0) {
        if (reserve((void **)&t->act, &t->acap, t->n + 1, sizeof(int32_t)) < 0 ||
            reserve((void **)&t->value, &t->vcap, t->n + 1, sizeof(double)) < 0)
            return -1;
        t->at[a] = t->n;
        t->act[t->n] = a;
        t->value[t->n++] = 0.0;
    }
    t->value[t->at[a]] += x;
    return 0;
}

static void tally_free(Tally *t) {
    PyMem_Free(t->at);
    PyMem_Free(t->act);
    PyMem_Free(t->value);
}

/* {name: value / total} (total: 1 for none) as a dict in the tally's order. */
static PyObject *tally_dict(Core *c, Tally *t, int divide, double total) {
    PyObject *out = PyDict_New();
    if (out == NULL) return NULL;
    for (Py_ssize_t i = 0; i < t->n; i++) {
        PyObject *v = PyFloat_FromDouble(divide ? t->value[i] / total : t->value[i]);
        if (v == NULL || PyDict_SetItem(out, PyList_GET_ITEM(c->names, t->act[i]), v) < 0) {
            Py_XDECREF(v);
            Py_DECREF(out);
            return NULL;
        }
        Py_DECREF(v);
    }
    return out;
}

static PyObject *beam_posterior(Beam *self, PyObject *unused) {
    Tally t;
    memset(&t, 0, sizeof(t));
    PyObject *out = NULL;
    if (self->depth > 0)
        for (Py_ssize_t i = 0; i < self->n; i++)
            if (tally_add(&t, self->node[i]->act, self->weight[i]) < 0) goto done;
    out = tally_dict(self->core, &t, 0, 1.0);
done:
    tally_free(&t);
    return out;
}

static PyObject *beam_predictive(Beam *self, PyObject *dyn) {
    Tally t;
    memset(&t, 0, sizeof(t));
    PyObject *out = NULL;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        Dist d;
        if (next_of(self, dyn, i, &d) < 0) goto done;
        for (Py_ssize_t k = 0; k < d.n; k++) {
            double x = self->weight[i] * d.p[k];
            if (tally_add(&t, d.act[k], x) < 0) goto done;
        }
    }
    double total = float_sum(t.value, t.n);
    if (total > 0)
        out = tally_dict(self->core, &t, 1, total);
    else
        out = PyDict_New();
done:
    tally_free(&t);
    return out;
}

static PyObject *beam_hypotheses(Beam *self, PyObject *dyn) {
    PyObject *out = PyList_New(self->n);
    if (out == NULL) return NULL;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        PyObject *cursor = node_cursor(self->core, self->node[i], dyn);
        PyObject *history = cursor ? node_history(self->core, self->node[i]) : NULL;
        PyObject *item = history ? Py_BuildValue("(dNO)", self->weight[i], history, cursor) : NULL;
        if (item == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        PyList_SET_ITEM(out, i, item);
    }
    return out;
}

static PyObject *beam_keys(Beam *self, PyObject *unused) {
    PyObject *out = PyList_New(self->n);
    if (out == NULL) return NULL;
    for (Py_ssize_t i = 0; i < self->n; i++) {
        PyObject *key = key_object(self->core, self->key[i]);
        if (key == NULL) {
            Py_DECREF(out);
            return NULL;
        }
        Py_INCREF(key);
        PyList_SET_ITEM(out, i, key);
    }
    return out;
}

static PyObject *beam_cursor(Beam *self, PyObject *args) {
    PyObject *dyn;
    Py_ssize_t i;
    if (!PyArg_ParseTuple(args, "On:cursor", &dyn, &i)) return NULL;
    if (i < 0 || i >= self->n) {
        PyErr_SetString(PyExc_IndexError, "cursor: no such history");
        return NULL;
    }
    PyObject *cursor = node_cursor(self->core, self->node[i], dyn);
    Py_XINCREF(cursor);
    return cursor;
}

static PyObject *beam_get_core(Beam *self, void *closure) {
    Py_INCREF(self->core);
    return (PyObject *)self->core;
}

static Py_ssize_t beam_len(Beam *self) { return self->n; }

/* -- Core's methods -------------------------------------------------------------------------------- */

/* The beam of a day start: one empty history, its cursor dyn.start() and key dyn.key(start). */
static PyObject *core_root(Core *self, PyObject *dyn) {
    if (core_ready(self) < 0) return NULL;
    PyObject *start = PyObject_CallMethodNoArgs(dyn, s_start);
    if (start == NULL) return NULL;
    PyObject *key = PyObject_CallMethodOneArg(dyn, s_key, start);
    Py_ssize_t k = -1;
    if (key != NULL && self->kind == OPAQUE) k = opaque_key(self, key);
    else if (key != NULL) { /* (tokens, start): the last `order` run labels, the current run's start */
        PyObject *tokens = PyTuple_Check(key) && PyTuple_GET_SIZE(key) == 2 ? PyTuple_GET_ITEM(key, 0) : NULL;
        PyObject *first = tokens ? PyTuple_GET_ITEM(key, 1) : NULL;
        Py_ssize_t n = tokens && PyTuple_Check(tokens) ? PyTuple_GET_SIZE(tokens) : 0;
        if (n < 1 || n > self->order || !PyLong_Check(first)) {
            PyErr_SetString(PyExc_ValueError, "root: a routine key is (a tuple of 1 to order labels, an int)");
        } else {
            long long s = PyLong_AsLongLong(first);
            int ok = !(s == -1 && PyErr_Occurred());
            for (Py_ssize_t i = 0; ok && i < n; i++) {
                int32_t a = activity_id(self, PyTuple_GET_ITEM(tokens, i));
                ok = a >= 0;
                self->scratch[i] = a;
            }
            if (ok && (k = routine_key(self, self->scratch, n, s)) >= 0 && self->keyobj[k] == NULL) {
                Py_INCREF(key);
                self->keyobj[k] = key;
            }
        }
    }
    Py_XDECREF(key);
    Beam *b = k >= 0 ? beam_new(self, 0, 1) : NULL;
    Node *node = b ? node_new(NULL, -1, start) : NULL;
    Py_DECREF(start);
    if (node == NULL) {
        Py_XDECREF(b);
        return NULL;
    }
    b->node[0] = node;
    b->weight[0] = 1.0;
    b->key[0] = k;
    b->rank[0] = 0;
    b->n = 1;
    return (PyObject *)b;
}

static PyObject *core_contexts(Core *self, PyObject *args) {
    PyObject *objects, *nothing_fn, *odds_fn;
    if (core_ready(self) < 0 || !PyArg_ParseTuple(args, "O!OO:contexts", &PyTuple_Type, &objects, &nothing_fn, &odds_fn))
        return NULL;
    Contexts *x = PyObject_New(Contexts, &ContextsType);
    if (x == NULL) return NULL;
    memset((char *)x + sizeof(PyObject), 0, sizeof(Contexts) - sizeof(PyObject));
    Py_INCREF(self);
    x->core = self;
    Py_INCREF(nothing_fn);
    x->nothing_fn = nothing_fn;
    Py_INCREF(odds_fn);
    x->odds_fn = odds_fn;
    x->objects = PyDict_New();
    x->object_names = PyList_New(0);
    if (x->objects == NULL || x->object_names == NULL) goto bad;
    for (Py_ssize_t i = 0; i < PyTuple_GET_SIZE(objects); i++) {
        PyObject *o = PyTuple_GET_ITEM(objects, i);
        int has = PyDict_Contains(x->objects, o);
        if (has < 0) goto bad;
        if (has) continue;
        PyObject *num = PyLong_FromSsize_t(x->nobj);
        int rc = num ? PyDict_SetItem(x->objects, o, num) : -1;
        Py_XDECREF(num);
        if (rc < 0 || PyList_Append(x->object_names, o) < 0) goto bad;
        x->nobj++;
    }
    Py_SETREF(x->object_names, PyList_AsTuple(x->object_names));
    if (x->object_names == NULL) goto bad;
    return (PyObject *)x;
bad:
    Py_DECREF(x);
    return NULL;
}

static PyObject *core_evidence(Core *self, PyObject *args) {
    PyObject *contexts, *upper, *switches;
    double weight, lam, log_lam, log1m_lam, log1m_zero;
    int boundary, switch_;
    if (core_ready(self) < 0 ||
        !PyArg_ParseTuple(args, "O!O!O!dddddpp:evidence", &ContextsType, &contexts, &PyTuple_Type, &upper, &PyTuple_Type,
                          &switches, &weight, &lam, &log_lam, &log1m_lam, &log1m_zero, &boundary, &switch_))
        return NULL;
    if (((Contexts *)contexts)->core != self) {
        PyErr_SetString(PyExc_ValueError, "evidence: the contexts belong to another core");
        return NULL;
    }
    Evidence *e = PyObject_New(Evidence, &EvidenceType);
    if (e == NULL) return NULL;
    memset((char *)e + sizeof(PyObject), 0, sizeof(Evidence) - sizeof(PyObject));
    Py_INCREF(self);
    e->core = self;
    Py_INCREF(contexts);
    e->contexts = (Contexts *)contexts;
    e->weight = weight;
    e->lam = lam;
    e->log_lam = log_lam;
    e->log1m_lam = log1m_lam;
    e->log1m_zero = log1m_zero;
    e->boundary = boundary;
    e->switch_ = switch_ && boundary;
    if ((e->moved = PyDict_New()) == NULL) goto bad;
    Py_ssize_t na = PyTuple_GET_SIZE(upper), ns = PyTuple_GET_SIZE(switches);
    int32_t *acts = PyMem_Malloc((size_t)(na ? na : 1) * sizeof(int32_t));
    if (acts == NULL) {
        PyErr_NoMemory();
        goto bad;
    }
    for (Py_ssize_t i = 0; i < na; i++)
        if ((acts[i] = activity_id(self, PyTuple_GET_ITEM(upper, i))) < 0) {
            PyMem_Free(acts);
            goto bad;
        }
    /* the activities the upper bound covers */
    e->nbounded = n_activities(self);
    e->bounded = PyMem_Calloc((size_t)(e->nbounded ? e->nbounded : 1), 1);
    /* the contexts of MovementEmission.upper_bound, in its order: each part, activity and flag,
     * then each switch seen (with the change flag, and the switch table on) */
    int flags = boundary ? 3 : 1;
    e->upper = PyMem_Malloc((size_t)(2 * na * flags + ns + 1) * sizeof(Py_ssize_t));
    if (e->bounded == NULL || e->upper == NULL) {
        PyMem_Free(acts);
        PyErr_NoMemory();
        goto bad;
    }
    for (Py_ssize_t i = 0; i < na; i++) e->bounded[acts[i]] = 1;
    for (int part = 0; part < 2; part++)
        for (Py_ssize_t i = 0; i < na; i++)
            for (int f = 0; f < flags; f++) {
                Py_ssize_t k = context_of(e->contexts, part, acts[i], f, -1);
                if (k < 0) {
                    PyMem_Free(acts);
                    goto bad;
                }
                e->upper[e->nupper++] = k;
            }
    PyMem_Free(acts);
    for (Py_ssize_t i = 0; i < ns; i++) {
        PyObject *pair = PyTuple_GET_ITEM(switches, i);
        if (!PyTuple_Check(pair) || PyTuple_GET_SIZE(pair) != 2) {
            PyErr_SetString(PyExc_TypeError, "evidence: a switch is a pair of activities");
            goto bad;
        }
        int32_t a = activity_id(self, PyTuple_GET_ITEM(pair, 0)), b = a < 0 ? -1 : activity_id(self, PyTuple_GET_ITEM(pair, 1));
        if (b < 0 || map_put(&e->switches, a, b, 0, 1) < 0) goto bad;
        if (e->switch_) {
            Py_ssize_t k = context_of(e->contexts, 0, a, FLAG_TRUE, b);
            if (k < 0) goto bad;
            e->upper[e->nupper++] = k;
        }
    }
    return (PyObject *)e;
bad:
    Py_DECREF(e);
    return NULL;
}

static PyObject *core_get_size(Core *self, void *closure) { return PyLong_FromSsize_t(self->nkeys); }

/* -- types and module ---------------------------------------------------------------------------- */

static PyMethodDef core_methods[] = {
    {"root", (PyCFunction)core_root, METH_O, "root(dynamics) -> the Beam of a day start"},
    {"contexts", (PyCFunction)core_contexts, METH_VARARGS,
     "contexts(objects, nothing_fn, odds_fn) -> the likelihood contexts of one emission's counts"},
    {"evidence", (PyCFunction)core_evidence, METH_VARARGS,
     "evidence(contexts, upper_activities, switches, weight, previous_share, log(share), log1p(-share), "
     "log1p(-0.0), boundary, switch) -> one emission setting's evidence"},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef core_getset[] = {
    {"size", (getter)core_get_size, NULL, "the number of states (keys) numbered so far", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PyTypeObject CoreType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "globe.models._filter_core.Core",
    .tp_basicsize = sizeof(Core),
    .tp_dealloc = (destructor)core_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Core(kind, order, dist_fn, child_fn): the numbered activities, states and memos of one model's dynamics",
    .tp_methods = core_methods,
    .tp_getset = core_getset,
    .tp_init = (initproc)core_init,
    .tp_new = PyType_GenericNew,
};

static PyMethodDef beam_methods[] = {
    {"advance", (PyCFunction)beam_advance, METH_VARARGS,
     "advance(dynamics, step, label, evidence, moved, min_weight, max_hypotheses, emission) -> the next Beam"},
    {"posterior", (PyCFunction)beam_posterior, METH_NOARGS, "P(the last activity) as ActivityFilter.posterior"},
    {"predictive", (PyCFunction)beam_predictive, METH_O, "predictive(dynamics): as ActivityFilter.predictive"},
    {"hypotheses", (PyCFunction)beam_hypotheses, METH_O, "hypotheses(dynamics) -> [(weight, history, cursor)]"},
    {"keys", (PyCFunction)beam_keys, METH_NOARGS, "the dynamics' key of each history"},
    {"cursor", (PyCFunction)beam_cursor, METH_VARARGS, "cursor(dynamics, i): the cursor of history i"},
    {NULL, NULL, 0, NULL},
};

static PyGetSetDef beam_getset[] = {
    {"core", (getter)beam_get_core, NULL, "the Core whose numbers this beam uses", NULL},
    {NULL, NULL, NULL, NULL, NULL},
};

static PySequenceMethods beam_sequence = {.sq_length = (lenfunc)beam_len};

static PyTypeObject BeamType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "globe.models._filter_core.Beam",
    .tp_basicsize = sizeof(Beam),
    .tp_dealloc = (destructor)beam_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "The weighted histories kept after a step (immutable; made by Core.root and Beam.advance)",
    .tp_methods = beam_methods,
    .tp_getset = beam_getset,
    .tp_as_sequence = &beam_sequence,
};

static PyTypeObject NodeType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "globe.models._filter_core.Node",
    .tp_basicsize = sizeof(Node),
    .tp_dealloc = (destructor)node_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "One history: its last activity and its parent",
};

static PyTypeObject ContextsType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "globe.models._filter_core.Contexts",
    .tp_basicsize = sizeof(Contexts),
    .tp_dealloc = (destructor)contexts_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "Per core and emission counts: each likelihood context's logs (made by Core.contexts)",
};

static PyTypeObject EvidenceType = {
    PyVarObject_HEAD_INIT(NULL, 0).tp_name = "globe.models._filter_core.Evidence",
    .tp_basicsize = sizeof(Evidence),
    .tp_dealloc = (destructor)evidence_dealloc,
    .tp_flags = Py_TPFLAGS_DEFAULT,
    .tp_doc = "One emission setting's upper bounds and likelihood rows by moved set (made by Core.evidence)",
};

/* Which sum() this interpreter has: plain or compensated; -1 (ImportError set) if neither. */
static int probe_sum(void) {
    static const double probes[][4] = {
        {1e16, 1.0, -1e16, 0.0}, {0.1, 0.2, 0.3, 0.4}, {1e308, 1e308, -1e308, 1.0}, {-0.0, 0.0, -0.0, 0.0},
        {3.0, 1e-16, 1e-16, -3.0}, {0.7, 0.1, 1e-17, 0.2},
    };
    PyObject *builtins = PyImport_ImportModule("builtins");
    PyObject *sum = builtins ? PyObject_GetAttrString(builtins, "sum") : NULL;
    Py_XDECREF(builtins);
    if (sum == NULL) return -1;
    int fits[2] = {1, 1};
    for (size_t i = 0; i < sizeof(probes) / sizeof(probes[0]); i++)
        for (Py_ssize_t n = 1; n <= 4; n++) {
            PyObject *list = PyList_New(n);
            if (list == NULL) goto bad;
            for (Py_ssize_t j = 0; j < n; j++) {
                PyObject *f = PyFloat_FromDouble(probes[i][j]);
                if (f == NULL) {
                    Py_DECREF(list);
                    goto bad;
                }
                PyList_SET_ITEM(list, j, f);
            }
            PyObject *r = PyObject_CallOneArg(sum, list);
            Py_DECREF(list);
            if (r == NULL) goto bad;
            double want = PyFloat_AsDouble(r);
            Py_DECREF(r);
            for (int mode = 0; mode < 2; mode++) {
                compensated_sum = mode;
                double got = float_sum(probes[i], n);
                if (memcmp(&got, &want, sizeof(double)) != 0) fits[mode] = 0;
            }
        }
    Py_DECREF(sum);
    if (!fits[0] && !fits[1]) {
        PyErr_SetString(PyExc_ImportError, "globe.models._filter_core: this interpreter's sum() adds floats differently");
        return -1;
    }
    compensated_sum = !fits[0];
    return 0;
bad:
    Py_DECREF(sum);
    return -1;
}

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_filter_core",
                                    "The activity filter's step in C (see globe.models.activity_filter).", -1, NULL};

PyMODINIT_FUNC PyInit__filter_core(void) {
    if (!no_contraction()) {
        PyErr_SetString(PyExc_ImportError, "globe.models._filter_core was built with fused multiply-adds; "
                                           "rebuild with -ffp-contract=off");
        return NULL;
    }
    if (probe_sum() < 0) return NULL;
    s_advance = PyUnicode_InternFromString("advance");
    s_start = PyUnicode_InternFromString("start");
    s_key = PyUnicode_InternFromString("key");
    if (!s_advance || !s_start || !s_key) return NULL;
    PyTypeObject *types[] = {&CoreType, &BeamType, &NodeType, &ContextsType, &EvidenceType};
    for (size_t i = 0; i < sizeof(types) / sizeof(types[0]); i++)
        if (PyType_Ready(types[i]) < 0) return NULL;
    PyObject *m = PyModule_Create(&module);
    if (m == NULL) return NULL;
    if (PyModule_AddIntConstant(m, "ROUTINE", ROUTINE) < 0 || PyModule_AddIntConstant(m, "OPAQUE", OPAQUE) < 0) goto bad;
    const char *names[] = {"Core", "Beam", "Node", "Contexts", "Evidence"};
    for (size_t i = 0; i < sizeof(types) / sizeof(types[0]); i++) {
        Py_INCREF(types[i]);
        if (PyModule_AddObject(m, names[i], (PyObject *)types[i]) < 0) {
            Py_DECREF(types[i]);
            goto bad;
        }
    }
    return m;
bad:
    Py_DECREF(m);
    return NULL;
}
