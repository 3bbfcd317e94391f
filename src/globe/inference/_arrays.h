/* The compiled kernels' arguments: a numpy array borrowed as C-contiguous memory of one kind,
 * checked before use. Each kernel defines KERNEL (its name, for the error messages) first. */
#ifndef GLOBE_ARRAYS_H
#define GLOBE_ARRAYS_H

#include <Python.h>

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
        PyErr_Format(PyExc_ValueError, KERNEL ": %s must be a contiguous %s%s array", what,
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
        PyErr_Format(PyExc_ValueError, KERNEL ": %s must be a contiguous %s array, not '%s'", what, kind_name(kind), f);
        return -1;
    }
    b->n = b->view.len / b->view.itemsize;
    return 0;
}

static void buf_release(Buf *b) {
    if (b->held) PyBuffer_Release(&b->view);
    b->held = 0;
}

#endif
