/* Appending training sequences to a SuffixIndex (globe/models/suffix_index.py): the one loop that
 * builds the automata of the n-gram models (appends, clones and redirections of the classic
 * online construction), returning the index's arrays with each state's further transitions in
 * insertion order.
 *
 * extend(ids, names, link, length, own, label1, target1, start, labels, targets, last, sequences)
 *   ids: dict label -> number and names: list number -> label (new labels are added to both);
 *   link, length, label1, target1, start, labels, targets: int32 buffers, own: int8 buffer, of a
 *   compacted index (start has one entry per state, plus one); last: the state of everything so
 *   far; sequences: a list of sequences of labels, each ending with the end marker.
 *   Returns (link, length, own, label1, target1, start, labels, targets) as bytes, and last.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    int32_t *label, *target;
    int32_t n, cap;
} Row; /* the further transitions of a state changed or created here, in insertion order */

typedef struct {
    int32_t *link, *len, *label1, *target1;
    int8_t *own;
    Row **rows;        /* NULL: the state's row of the old table (or none, for a new state) */
    Py_ssize_t n, cap; /* states */
    const int32_t *start, *labels, *targets;
    Py_ssize_t old; /* states with a row in the old table */
} Automaton;

static int grow(Automaton *a) {
    if (a->n < a->cap) return 0;
    Py_ssize_t cap = a->cap ? 2 * a->cap : 64;
    int32_t *link = PyMem_Realloc(a->link, cap * sizeof(int32_t));
    if (link) a->link = link;
    int32_t *len = PyMem_Realloc(a->len, cap * sizeof(int32_t));
    if (len) a->len = len;
    int32_t *label1 = PyMem_Realloc(a->label1, cap * sizeof(int32_t));
    if (label1) a->label1 = label1;
    int32_t *target1 = PyMem_Realloc(a->target1, cap * sizeof(int32_t));
    if (target1) a->target1 = target1;
    int8_t *own = PyMem_Realloc(a->own, cap * sizeof(int8_t));
    if (own) a->own = own;
    Row **rows = PyMem_Realloc(a->rows, cap * sizeof(Row *));
    if (rows) a->rows = rows;
    if (!link || !len || !label1 || !target1 || !own || !rows) {
        PyErr_NoMemory();
        return -1;
    }
    memset(a->rows + a->cap, 0, (cap - a->cap) * sizeof(Row *));
    a->cap = cap;
    return 0;
}

static int32_t new_state(Automaton *a, int32_t len, int32_t link, int8_t own, int32_t label1, int32_t target1) {
    if (grow(a) < 0) return -1;
    Py_ssize_t s = a->n++;
    a->len[s] = len;
    a->link[s] = link;
    a->own[s] = own;
    a->label1[s] = label1;
    a->target1[s] = target1;
    a->rows[s] = NULL;
    return (int32_t)s;
}

static int row_append(Row *r, int32_t label, int32_t target) {
    if (r->n == r->cap) {
        int32_t cap = r->cap ? 2 * r->cap : 4;
        int32_t *l = PyMem_Realloc(r->label, cap * sizeof(int32_t));
        if (l) r->label = l;
        int32_t *t = PyMem_Realloc(r->target, cap * sizeof(int32_t));
        if (t) r->target = t;
        if (!l || !t) {
            PyErr_NoMemory();
            return -1;
        }
        r->cap = cap;
    }
    r->label[r->n] = label;
    r->target[r->n] = target;
    r->n++;
    return 0;
}

/* A new row holding `count` transitions (copied). */
static Row *row_copy(const int32_t *label, const int32_t *target, int32_t count) {
    Row *r = PyMem_Calloc(1, sizeof(Row));
    if (r == NULL) {
        PyErr_NoMemory();
        return NULL;
    }
    for (int32_t i = 0; i < count; i++) {
        if (row_append(r, label[i], target[i]) < 0) {
            PyMem_Free(r->label);
            PyMem_Free(r->target);
            PyMem_Free(r);
            return NULL;
        }
    }
    return r;
}

/* The state's further transitions as they are now: its changed row, else its old one. */
static Row *own_row(Automaton *a, int32_t s) {
    if (a->rows[s] != NULL) return a->rows[s];
    if (s < a->old) {
        int32_t lo = a->start[s], hi = a->start[s + 1];
        a->rows[s] = row_copy(a->labels + lo, a->targets + lo, hi - lo);
    } else {
        a->rows[s] = row_copy(NULL, NULL, 0);
    }
    return a->rows[s];
}

/* Position of `label` among the further transitions of `s` (-1: none); *in_row: in a changed row. */
static int32_t find(Automaton *a, int32_t s, int32_t label, int32_t *target) {
    Row *r = a->rows[s];
    if (r != NULL) {
        for (int32_t i = 0; i < r->n; i++)
            if (r->label[i] == label) {
                *target = r->target[i];
                return i;
            }
        return -1;
    }
    if (s < a->old) {
        for (int32_t i = a->start[s]; i < a->start[s + 1]; i++)
            if (a->labels[i] == label) {
                *target = a->targets[i];
                return i;
            }
    }
    return -1;
}

/* Target of `s` on `label`, -1 if none (SuffixIndex._get). */
static int32_t get(Automaton *a, int32_t s, int32_t label) {
    if (a->label1[s] == label) return a->target1[s];
    int32_t t;
    return find(a, s, label, &t) >= 0 ? t : -1;
}

/* Add the transition `s` --label--> target (`label` is not among s's further transitions yet). */
static int add_edge(Automaton *a, int32_t s, int32_t label, int32_t target) {
    Row *r = own_row(a, s);
    return r == NULL ? -1 : row_append(r, label, target);
}

/* Redirect an existing further transition of `s` on `label` (it keeps its place). */
static int redirect(Automaton *a, int32_t s, int32_t label, int32_t target) {
    Row *r = own_row(a, s);
    if (r == NULL) return -1;
    for (int32_t i = 0; i < r->n; i++)
        if (r->label[i] == label) {
            r->target[i] = target;
            return 0;
        }
    return 0;
}

/* One label appended after `last`: the new last state, or -1 on error. */
static int32_t extend_one(Automaton *a, int32_t last, int32_t c) {
    int32_t cur = new_state(a, a->len[last] + 1, 0, 1, -1, -1);
    if (cur < 0) return -1;
    int32_t p = last, q = -1;
    while (p != -1) {
        if (a->label1[p] == c) {
            q = a->target1[p];
            break;
        }
        if (a->label1[p] == -1) {
            a->label1[p] = c;
            a->target1[p] = cur;
        } else {
            q = get(a, p, c);
            if (q != -1) break;
            if (add_edge(a, p, c, cur) < 0) return -1;
        }
        p = a->link[p];
    }
    if (p != -1) {
        if (a->len[p] + 1 == a->len[q]) {
            a->link[cur] = q;
        } else {
            int32_t clone = new_state(a, a->len[p] + 1, a->link[q], 0, a->label1[q], a->target1[q]);
            if (clone < 0) return -1;
            /* the clone's further transitions: a copy of q's (none if q has none) */
            if (a->rows[q] != NULL) {
                if (a->rows[q]->n > 0 && (a->rows[clone] = row_copy(a->rows[q]->label, a->rows[q]->target, a->rows[q]->n)) == NULL)
                    return -1;
            } else if (q < a->old && a->start[q + 1] > a->start[q]) {
                int32_t lo = a->start[q];
                if ((a->rows[clone] = row_copy(a->labels + lo, a->targets + lo, a->start[q + 1] - lo)) == NULL) return -1;
            }
            while (p != -1) {
                if (a->label1[p] == c) {
                    if (a->target1[p] != q) break;
                    a->target1[p] = clone;
                } else {
                    int32_t t;
                    if (find(a, p, c, &t) < 0 || t != q) break;
                    if (redirect(a, p, c, clone) < 0) return -1;
                }
                p = a->link[p];
            }
            a->link[q] = clone;
            a->link[cur] = clone;
        }
    }
    return cur;
}

static void release(Automaton *a) {
    if (a->rows != NULL)
        for (Py_ssize_t s = 0; s < a->n; s++)
            if (a->rows[s] != NULL) {
                PyMem_Free(a->rows[s]->label);
                PyMem_Free(a->rows[s]->target);
                PyMem_Free(a->rows[s]);
            }
    PyMem_Free(a->rows);
    PyMem_Free(a->link);
    PyMem_Free(a->len);
    PyMem_Free(a->label1);
    PyMem_Free(a->target1);
    PyMem_Free(a->own);
}

/* The label's number, added to ids and names when new; -1 on error. */
static int32_t number_of(PyObject *ids, PyObject *names, PyObject *label) {
    PyObject *number = PyDict_GetItemWithError(ids, label);
    if (number != NULL) return (int32_t)PyLong_AsLong(number);
    if (PyErr_Occurred()) return -1;
    Py_ssize_t c = PyList_GET_SIZE(names);
    PyObject *n = PyLong_FromSsize_t(c);
    if (n == NULL) return -1;
    int rc = PyDict_SetItem(ids, label, n);
    Py_DECREF(n);
    if (rc < 0 || PyList_Append(names, label) < 0) return -1;
    return (int32_t)c;
}

static PyObject *int32_bytes(const int32_t *data, Py_ssize_t n) {
    return PyBytes_FromStringAndSize((const char *)data, n * (Py_ssize_t)sizeof(int32_t));
}

/* The compacted table of further transitions: per state its changed row, else its old row. */
static PyObject *table(Automaton *a, PyObject **labels_out, PyObject **targets_out) {
    Py_ssize_t total = 0;
    for (Py_ssize_t s = 0; s < a->n; s++)
        total += a->rows[s] != NULL ? a->rows[s]->n : (s < a->old ? a->start[s + 1] - a->start[s] : 0);
    PyObject *start = PyBytes_FromStringAndSize(NULL, (a->n + 1) * (Py_ssize_t)sizeof(int32_t));
    PyObject *labels = PyBytes_FromStringAndSize(NULL, total * (Py_ssize_t)sizeof(int32_t));
    PyObject *targets = PyBytes_FromStringAndSize(NULL, total * (Py_ssize_t)sizeof(int32_t));
    if (!start || !labels || !targets) {
        Py_XDECREF(start);
        Py_XDECREF(labels);
        Py_XDECREF(targets);
        return NULL;
    }
    int32_t *st = (int32_t *)PyBytes_AS_STRING(start), *lb = (int32_t *)PyBytes_AS_STRING(labels),
            *tg = (int32_t *)PyBytes_AS_STRING(targets);
    int32_t k = 0;
    for (Py_ssize_t s = 0; s < a->n; s++) {
        st[s] = k;
        if (a->rows[s] != NULL) {
            memcpy(lb + k, a->rows[s]->label, a->rows[s]->n * sizeof(int32_t));
            memcpy(tg + k, a->rows[s]->target, a->rows[s]->n * sizeof(int32_t));
            k += a->rows[s]->n;
        } else if (s < a->old) {
            int32_t lo = a->start[s], m = a->start[s + 1] - lo;
            memcpy(lb + k, a->labels + lo, m * sizeof(int32_t));
            memcpy(tg + k, a->targets + lo, m * sizeof(int32_t));
            k += m;
        }
    }
    st[a->n] = k;
    *labels_out = labels;
    *targets_out = targets;
    return start;
}

static PyObject *extend(PyObject *self, PyObject *args) {
    PyObject *ids, *names, *sequences;
    PyObject *objs[8];
    Py_buffer views[8];
    long last;
    if (!PyArg_ParseTuple(args, "O!O!OOOOOOOOlO!", &PyDict_Type, &ids, &PyList_Type, &names, &objs[0], &objs[1], &objs[2],
                          &objs[3], &objs[4], &objs[5], &objs[6], &objs[7], &last, &PyList_Type, &sequences))
        return NULL;
    /* link, length, own, label1, target1, start, labels, targets */
    const Py_ssize_t item[8] = {4, 4, 1, 4, 4, 4, 4, 4};
    int got = 0;
    Automaton a;
    memset(&a, 0, sizeof(a));
    PyObject *out = NULL;
    for (; got < 8; got++) {
        if (PyObject_GetBuffer(objs[got], &views[got], PyBUF_FORMAT) < 0) goto done;
        if (views[got].itemsize != item[got]) {
            got++;
            PyErr_SetString(PyExc_TypeError, "extend: unexpected array item size");
            goto done;
        }
    }
    Py_ssize_t n = views[1].len / 4;
    if (views[0].len / 4 != n || views[2].len != n || views[3].len / 4 != n || views[4].len / 4 != n ||
        views[5].len / 4 != n + 1 || views[6].len != views[7].len || last < 0 || last >= n) {
        PyErr_SetString(PyExc_ValueError, "extend: the index is not compacted, or its arrays disagree");
        goto done;
    }
    a.start = views[5].buf;
    a.labels = views[6].buf;
    a.targets = views[7].buf;
    a.old = n;
    /* every state number in range and the table well formed: a damaged index is an error, never a bad read */
    {
        const int32_t *link = views[0].buf, *target1 = views[4].buf;
        Py_ssize_t nlab = views[6].len / 4;
        int ok = a.start[0] == 0 && a.start[n] == nlab && views[6].len % 4 == 0;
        for (Py_ssize_t s = 0; ok && s < n; s++)
            ok = a.start[s] <= a.start[s + 1] && link[s] >= -1 && link[s] < n && target1[s] >= -1 && target1[s] < n;
        for (Py_ssize_t i = 0; ok && i < nlab; i++) ok = a.targets[i] >= 0 && a.targets[i] < n;
        if (!ok) {
            PyErr_SetString(PyExc_ValueError, "extend: the index's arrays are damaged");
            goto done;
        }
    }
    for (Py_ssize_t s = 0; s < n; s++)
        if (new_state(&a, ((int32_t *)views[1].buf)[s], ((int32_t *)views[0].buf)[s], ((int8_t *)views[2].buf)[s],
                      ((int32_t *)views[3].buf)[s], ((int32_t *)views[4].buf)[s]) < 0)
            goto done;
    int32_t cur = (int32_t)last;
    for (Py_ssize_t i = 0; i < PyList_GET_SIZE(sequences); i++) {
        PyObject *seq = PySequence_Fast(PyList_GET_ITEM(sequences, i), "extend: a sequence must be a list or tuple");
        if (seq == NULL) goto done;
        for (Py_ssize_t j = 0; j < PySequence_Fast_GET_SIZE(seq); j++) {
            int32_t c = number_of(ids, names, PySequence_Fast_GET_ITEM(seq, j));
            if (c < 0 || (cur = extend_one(&a, cur, c)) < 0) {
                Py_DECREF(seq);
                goto done;
            }
        }
        Py_DECREF(seq);
    }
    PyObject *labels = NULL, *targets = NULL;
    PyObject *start = table(&a, &labels, &targets);
    if (start == NULL) goto done;
    out = Py_BuildValue("(NNNNNNNN)l", int32_bytes(a.link, a.n), int32_bytes(a.len, a.n),
                        PyBytes_FromStringAndSize((const char *)a.own, a.n), int32_bytes(a.label1, a.n),
                        int32_bytes(a.target1, a.n), start, labels, targets, (long)cur);
done:
    for (int i = 0; i < got; i++) PyBuffer_Release(&views[i]);
    release(&a);
    return out;
}

static PyMethodDef methods[] = {
    {"extend", extend, METH_VARARGS, "Append sequences to a compacted suffix automaton; returns its new arrays."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_suffix_automaton", NULL, -1, methods};

PyMODINIT_FUNC PyInit__suffix_automaton(void) { return PyModule_Create(&module); }
