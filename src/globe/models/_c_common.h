/* Small helpers shared by the compiled model parts (_filter_core.c, _forecast_core.c): each
 * includes this header once, so the functions are static to each extension. */

#ifndef GLOBE_C_COMMON_H
#define GLOBE_C_COMMON_H

#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

/* Make room for `need` items of `size` bytes in the array *p of *cap items. */
static inline int reserve(void **p, Py_ssize_t *cap, Py_ssize_t need, size_t size) {
    if (need <= *cap) return 0;
    Py_ssize_t cap2 = *cap ? *cap : 16;
    while (cap2 < need) cap2 *= 2;
    void *q = PyMem_Realloc(*p, (size_t)cap2 * size);
    if (q == NULL) {
        PyErr_NoMemory();
        return -1;
    }
    *p = q;
    *cap = cap2;
    return 0;
}

/* A 64-bit finaliser for hash tables keyed by integers. */
static inline uint64_t mix64(uint64_t h) {
    h ^= h >> 31;
    h *= 0x94D049BB133111EBULL;
    h ^= h >> 29;
    return h;
}

typedef int (*Before)(const void *ctx, Py_ssize_t a, Py_ssize_t b); /* 1: a goes strictly before b */

/* Stable merge sort of idx[0..n) by before(ctx, ., .) (tmp: room for n). */
static void sort_indices(Py_ssize_t *idx, Py_ssize_t *tmp, Py_ssize_t n, Before before, const void *ctx) {
    if (n < 2) return;
    Py_ssize_t h = n / 2;
    sort_indices(idx, tmp, h, before, ctx);
    sort_indices(idx + h, tmp, n - h, before, ctx);
    Py_ssize_t i = 0, j = h, k = 0;
    while (i < h && j < n) tmp[k++] = before(ctx, idx[j], idx[i]) ? idx[j++] : idx[i++];
    while (i < h) tmp[k++] = idx[i++];
    while (j < n) tmp[k++] = idx[j++];
    memcpy(idx, tmp, (size_t)n * sizeof(Py_ssize_t));
}

/* 1 where a * b + c is rounded twice, as Python and numpy round each operation (no fused
 * multiply-add): the compiled parts must give their numbers to the bit. */
static inline int no_contraction(void) {
    volatile double a = 1.0 + 1.0 / 1073741824.0, b = 1.0 - 1.0 / 1073741824.0, c = -1.0;
    double x = a, y = b, z = c;
    double r = x * y + z;
    return r == 0.0;
}

#endif
