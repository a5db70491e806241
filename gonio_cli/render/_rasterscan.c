/* The rasterizer's depth test in C: the C build of visibility._scan, one triangle at a time.
 *
 * Why C: the numpy build batches (triangle, row) pairs into spans and scatters the hits'
 * keys with np.minimum.at; on a 512² frame of the 20 448-triangle sphere that is 10-20 ms of
 * temporaries and scatter, a fifth of a frame, where this loop takes ~1-2 ms. Built by pip
 * as _envlookup.c (optional; visibility.py falls back to numpy where it was not built).
 * -ffp-contract=off: no fused multiply-add, so every float32 operation below is the one the
 * numpy build performs and the keys are equal bit for bit (tests/test_render_raster.py).
 *
 * Per kept triangle t of sel and row y of its box: the columns that can show it, from the
 * roots of its edge functions in float64 widened by the float32 round-off of the test
 * (slack, as visibility._scan computes it); on each of them the float32 test itself,
 *     dy = (cy − y) inv_f,  e_k = dx C_k.x + (dy C_k.y + C_k.z),  shown iff min_k e_k ≥ 0,
 * and at a hit 1/z = dx iz.x + (dy iz.y + iz.z), kept when 0 < 1/z < 1/NEAR, and the key
 * (0x7FFFFFFF − float32 bits of 1/z) << 32 | bits[t] min-ed into keys[y w + col].
 *
 * Interface (checked by visibility.py; buffers C-contiguous):
 *   scan(C, iz, bits, x0, y0, bw, bh, sel, dx_col, n, m, w, h, F, cy, inv_f, inv_near,
 *        tol, keys) -> None
 *   C float32 (3 edges, 3, n); iz float32 (3, n); bits, x0, y0, bw, bh int64 (n,);
 *   sel int64 (m,) the triangles to test; dx_col float32 (w,); keys int64 (h w,) in/out.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>
#include <string.h>

typedef struct {
    const float *C, *iz, *dx_col;
    const int64_t *bits, *x0, *y0, *bw, *bh;
    Py_ssize_t n, w;
    double F, cx, tol;
    float cy, inv_f, inv_near;
    int64_t *keys;
} Scan;

/* Column bounds [lo, hi] of row y that can show triangle t (lo > hi: none). */
static void row_bounds(const Scan *s, Py_ssize_t t, const double A_out[3], const double B[3],
                       const int kind[3], int64_t y, int64_t *lo, int64_t *hi) {
    double l = (double)s->x0[t], u = (double)(s->x0[t] + s->bw[t] - 1);
    for (int k = 0; k < 3; k++) {
        double root = A_out[k] + B[k] * (double)y;       /* the root widened by its slack */
        if (kind[k] > 0 && root > l) l = root;
        if (kind[k] < 0 && root < u) u = root;
    }
    if (!(l <= u)) {                                  /* also a NaN or an infinite root */
        *lo = 1;
        *hi = 0;
        return;
    }
    *lo = (int64_t)ceil(l);
    *hi = (int64_t)floor(u);
}

static void triangle(const Scan *s, Py_ssize_t t) {
    float c[3][3];
    double A[3], B[3], A_out[3];
    int kind[3];                                     /* +1 lower edge, −1 upper, 0 flat */
    const Py_ssize_t n = s->n;
    const int64_t y0 = s->y0[t], y1 = s->y0[t] + s->bh[t] - 1;
    for (int k = 0; k < 3; k++) {
        for (int i = 0; i < 3; i++) c[k][i] = s->C[(k * 3 + i) * n + t];
        double cxk = (double)c[k][0], cyk = (double)c[k][1], czk = (double)c[k][2];
        kind[k] = cxk > 0.0 ? 1 : (cxk < 0.0 ? -1 : 0);
        double safe = kind[k] ? cxk : 1.0;
        A[k] = s->cx - (s->F * czk + (double)s->cy * cyk) / safe;
        B[k] = kind[k] ? cyk / safe : 0.0;
        double a0 = fabs(A[k] + B[k] * (double)y0 - s->cx);
        double a1 = fabs(A[k] + B[k] * (double)y1 - s->cx);
        double slack = s->tol * (a0 > a1 ? a0 : a1) + s->tol * ((double)s->w / 2.0 + 1.0);
        A_out[k] = kind[k] > 0 ? A[k] - slack : A[k] + slack;
    }
    const float iz0 = s->iz[t], iz1 = s->iz[n + t], iz2 = s->iz[2 * n + t];
    const int64_t bits = s->bits[t];
    for (int64_t y = y0; y <= y1; y++) {
        int64_t lo, hi;
        row_bounds(s, t, A_out, B, kind, y, &lo, &hi);
        if (lo > hi) continue;
        const float dy = (s->cy - (float)y) * s->inv_f;
        const float r0 = dy * c[0][1] + c[0][2], r1 = dy * c[1][1] + c[1][2];
        const float r2 = dy * c[2][1] + c[2][2], rzc = dy * iz1 + iz2;
        int64_t *row = s->keys + y * s->w;
        for (int64_t col = lo; col <= hi; col++) {
            const float dx = s->dx_col[col];
            float e = dx * c[0][0] + r0, e1 = dx * c[1][0] + r1, e2 = dx * c[2][0] + r2;
            if (e1 < e) e = e1;
            if (e2 < e) e = e2;
            if (!(e >= 0.0f)) continue;
            const float rz = dx * iz0 + rzc;
            if (!(rz > 0.0f && rz < s->inv_near)) continue;
            int32_t b;
            memcpy(&b, &rz, sizeof b);
            const int64_t key = (((int64_t)0x7FFFFFFF - (int64_t)b) << 32) | bits;
            if (key < row[col]) row[col] = key;
        }
    }
}

static PyObject *scan(PyObject *self, PyObject *args) {
    Py_buffer bC, biz, bbits, bx0, by0, bbw, bbh, bsel, bdx, bkeys;
    Py_ssize_t n, m, w, h;
    double F, cy, inv_f, inv_near, tol;
    if (!PyArg_ParseTuple(args, "y*y*y*y*y*y*y*y*y*nnnndddddw*", &bC, &biz, &bbits, &bx0, &by0,
                          &bbw, &bbh, &bsel, &bdx, &n, &m, &w, &h, &F, &cy, &inv_f, &inv_near,
                          &tol, &bkeys))
        return NULL;
    PyObject *result = NULL;
    if (bC.len != (Py_ssize_t)(9 * n * sizeof(float)) || biz.len != (Py_ssize_t)(3 * n * sizeof(float))
            || bsel.len != (Py_ssize_t)(m * sizeof(int64_t))
            || bdx.len != (Py_ssize_t)(w * sizeof(float))
            || bkeys.len != (Py_ssize_t)(w * h * sizeof(int64_t))) {
        PyErr_SetString(PyExc_ValueError, "_rasterscan.scan: buffer sizes do not match");
        goto done;
    }
    Scan s = {bC.buf, biz.buf, bdx.buf, bbits.buf, bx0.buf, by0.buf, bbw.buf, bbh.buf, n, w,
              F, (double)(float)((double)w / 2.0 - 0.5), tol, (float)cy, (float)inv_f,
              (float)inv_near, bkeys.buf};
    const int64_t *sel = bsel.buf;
    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t i = 0; i < m; i++) triangle(&s, (Py_ssize_t)sel[i]);
    Py_END_ALLOW_THREADS
    result = Py_None;
    Py_INCREF(result);
done:
    PyBuffer_Release(&bC); PyBuffer_Release(&biz); PyBuffer_Release(&bbits);
    PyBuffer_Release(&bx0); PyBuffer_Release(&by0); PyBuffer_Release(&bbw);
    PyBuffer_Release(&bbh); PyBuffer_Release(&bsel); PyBuffer_Release(&bdx);
    PyBuffer_Release(&bkeys);
    return result;
}

static PyMethodDef methods[] = {
    {"scan", scan, METH_VARARGS, "The rasterizer's depth test (see header)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_rasterscan",
                                    "The depth test of render.visibility in C.", -1, methods};

PyMODINIT_FUNC PyInit__rasterscan(void) { return PyModule_Create(&module); }
