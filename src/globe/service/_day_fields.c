/* Splitting a day file's text into its fields, in C: exactly what
 * globe.service.upload._day_fields_python returns, without making a string of every line and of
 * every line's locations (a HOMER+ day is about 100 KB; its locations repeat line after line).
 * Optional: without it GLOBE runs the Python function.
 *
 * day_fields(text) -> None, or (minutes, activities, starts, changed):
 *   None when the text has a blank line (a last empty line, from a final newline, aside), no line
 *   after the header, or a line after the header with fewer than two commas;
 *   minutes, activities: tuples of each line's first and second cell (lines after the header);
 *   starts: the indices (among those lines) where the rest of the line (its locations) differs
 *   from the line before's, 0 first; changed: that rest at each of them.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <string.h>

static Py_ssize_t find_char(int kind, const void *data, Py_ssize_t from, Py_ssize_t to, Py_UCS4 ch) {
    if (kind == PyUnicode_1BYTE_KIND) { /* ASCII and Latin-1 texts, the usual case */
        if (from >= to) return -1;
        const char *at = memchr((const char *)data + from, (int)ch, (size_t)(to - from));
        return at == NULL ? -1 : at - (const char *)data;
    }
    for (Py_ssize_t i = from; i < to; i++)
        if (PyUnicode_READ(kind, data, i) == ch) return i;
    return -1;
}

static PyObject *day_fields(PyObject *self, PyObject *arg) {
    (void)self;
    if (!PyUnicode_Check(arg)) {
        PyErr_SetString(PyExc_TypeError, "day_fields: expected a str");
        return NULL;
    }
    if (PyUnicode_READY(arg) < 0) return NULL;
    int kind = PyUnicode_KIND(arg);
    const void *data = PyUnicode_DATA(arg);
    const char *bytes = (const char *)data;
    Py_ssize_t n = PyUnicode_GET_LENGTH(arg), end = n;
    if (n > 0 && PyUnicode_READ(kind, data, n - 1) == '\n') end = n - 1; /* the last line is empty: dropped */
    /* the header: up to the first newline */
    Py_ssize_t pos = find_char(kind, data, 0, end, '\n');
    if (pos == 0) Py_RETURN_NONE; /* a blank header line */
    if (pos < 0) Py_RETURN_NONE;  /* no line after the header */
    PyObject *minutes = PyList_New(0), *activities = PyList_New(0), *starts = PyList_New(0), *changed = PyList_New(0);
    PyObject *out = NULL;
    if (!minutes || !activities || !starts || !changed) goto done;
    Py_ssize_t line = 0, prev_lo = -1, prev_hi = -1;
    Py_ssize_t start = pos + 1;
    int blank = 0;
    while (1) {
        Py_ssize_t stop = start <= end ? find_char(kind, data, start, end, '\n') : -1;
        if (stop < 0) stop = end;
        if (stop <= start) { /* an empty line (or a text ending in two newlines) */
            blank = 1;
            break;
        }
        Py_ssize_t c1 = find_char(kind, data, start, stop, ',');
        Py_ssize_t c2 = c1 < 0 ? -1 : find_char(kind, data, c1 + 1, stop, ',');
        if (c2 < 0) {
            blank = 1; /* fewer than three cells: not for the fast path */
            break;
        }
        PyObject *m = PyUnicode_Substring(arg, start, c1);
        if (m == NULL || PyList_Append(minutes, m) < 0) { Py_XDECREF(m); goto done; }
        Py_DECREF(m);
        PyObject *a = PyUnicode_Substring(arg, c1 + 1, c2);
        if (a == NULL || PyList_Append(activities, a) < 0) { Py_XDECREF(a); goto done; }
        Py_DECREF(a);
        Py_ssize_t lo = c2 + 1, hi = stop;
        if (prev_lo < 0 || hi - lo != prev_hi - prev_lo || memcmp(bytes + lo * kind, bytes + prev_lo * kind, (size_t)(hi - lo) * kind) != 0) {
            PyObject *i = PyLong_FromSsize_t(line);
            if (i == NULL || PyList_Append(starts, i) < 0) { Py_XDECREF(i); goto done; }
            Py_DECREF(i);
            PyObject *t = PyUnicode_Substring(arg, lo, hi);
            if (t == NULL || PyList_Append(changed, t) < 0) { Py_XDECREF(t); goto done; }
            Py_DECREF(t);
        }
        prev_lo = lo;
        prev_hi = hi;
        line++;
        if (stop >= end) break;
        start = stop + 1;
    }
    if (blank) {
        out = Py_None;
        Py_INCREF(out);
        goto done;
    }
    {
        PyObject *mt = PyList_AsTuple(minutes), *at = PyList_AsTuple(activities);
        if (mt && at) out = Py_BuildValue("(NNOO)", mt, at, starts, changed);
        else { Py_XDECREF(mt); Py_XDECREF(at); }
    }
done:
    Py_XDECREF(minutes);
    Py_XDECREF(activities);
    Py_XDECREF(starts);
    Py_XDECREF(changed);
    return out;
}

static PyMethodDef methods[] = {
    {"day_fields", day_fields, METH_O, "A day text's minutes, activities and changes of locations (see the module)."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_day_fields", NULL, -1, methods, NULL, NULL, NULL, NULL};

PyMODINIT_FUNC PyInit__day_fields(void) { return PyModule_Create(&module); }
