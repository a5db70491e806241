/* Vector error diffusion over the four exclusive ink states {none, R, G, B}: the C build of
 * the kernel in diffusion.py (_kernel_source), statement for statement.
 *
 * Why C beside numba: a halftone is one call of this loop, and in a fresh process numba's
 * import and the loading of its cached kernel cost ~0.7 s, more than the loop itself
 * (0.3 s at 4096²). This module is built by pip when gonio is installed (a C compiler and
 * the Python headers); where it could not be built, diffusion.py uses the numba kernel.
 * Both add the same float64 products in the same order as diffusion.diffuse_reference, so
 * the three give identical labels (tests/test_halftone.py checks every path).
 *
 * Build flags: -ffp-contract=off keeps a*b+c from becoming one fused multiply-add, which
 * would round differently from the reference (setup in pyproject.toml).
 *
 * Interface (all checked by diffusion.py before the call; buffers are C-contiguous):
 *   run(coverage, pixels, h, w, channels, table, scale_limit, dy, dx, wt, serpentine,
 *       labels, stats) -> None
 *   coverage  float32 (h, w, 3) or empty when pixels are given
 *   pixels    uint8 (h, w, channels) or empty
 *   table     float32 (256,)    decoding of a stored 8-bit value to linear coverage
 *   dy, dx    int64 (n,)        taps; wt float64 (n,) weights
 *   labels    uint8 (h, w)      output: 0 substrate, k = 1, 2, 3 ink k
 *   stats     float64 (4,)      output: pixels out of gamut, then the sum of each ink
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

static PyObject *run(PyObject *self, PyObject *args) {
    Py_buffer cov, pix, tab, bdy, bdx, bwt, blab, bst;
    Py_ssize_t h, w, channels;
    float scale_limit;
    int serpentine;
    if (!PyArg_ParseTuple(args, "y*y*nnny*fy*y*y*pw*w*", &cov, &pix, &h, &w, &channels,
                          &tab, &scale_limit, &bdy, &bdx, &bwt, &serpentine, &blab, &bst))
        return NULL;
    const float *coverage = (const float *)cov.buf;
    const uint8_t *pixels = (const uint8_t *)pix.buf;
    const float *table = (const float *)tab.buf;
    const int64_t *dy = (const int64_t *)bdy.buf;
    const int64_t *dx = (const int64_t *)bdx.buf;
    const double *wt = (const double *)bwt.buf;
    uint8_t *labels = (uint8_t *)blab.buf;
    double *stats = (double *)bst.buf;
    Py_ssize_t n = bwt.len / (Py_ssize_t)sizeof(double);
    int from_pixels = pix.len > 0;

    Py_ssize_t rows = 1, pad = 0;
    for (Py_ssize_t t = 0; t < n; t++) {
        if (dy[t] + 1 > rows) rows = dy[t] + 1;
        Py_ssize_t a = dx[t] < 0 ? -dx[t] : dx[t];
        if (a > pad) pad = a;
    }
    Py_ssize_t stride = (w + 2 * pad) * 3;
    double *err = PyMem_Calloc((size_t)(rows * stride), sizeof(double));
    Py_ssize_t *ring = PyMem_Malloc((size_t)(n > 0 ? n : 1) * sizeof(Py_ssize_t));
    Py_ssize_t *offset = PyMem_Malloc((size_t)(n > 0 ? n : 1) * sizeof(Py_ssize_t));
    if (err == NULL || ring == NULL || offset == NULL) {
        PyMem_Free(err); PyMem_Free(ring); PyMem_Free(offset);
        PyBuffer_Release(&cov); PyBuffer_Release(&pix); PyBuffer_Release(&tab);
        PyBuffer_Release(&bdy); PyBuffer_Release(&bdx); PyBuffer_Release(&bwt);
        PyBuffer_Release(&blab); PyBuffer_Release(&bst);
        return PyErr_NoMemory();
    }
    double outside = 0.0, sum0 = 0.0, sum1 = 0.0, sum2 = 0.0;

    Py_BEGIN_ALLOW_THREADS
    for (Py_ssize_t y = 0; y < h; y++) {
        Py_ssize_t cur = y % rows;
        Py_ssize_t step = (serpentine && (y % 2 == 1)) ? -1 : 1;
        for (Py_ssize_t t = 0; t < n; t++) {
            ring[t] = (cur + dy[t]) % rows;
            offset[t] = step * dx[t];
        }
        double *row = err + cur * stride;
        for (Py_ssize_t i = 0; i < w; i++) {
            Py_ssize_t x = step == 1 ? i : w - 1 - i;
            Py_ssize_t xe = x + pad;
            float c0, c1, c2;
            if (from_pixels) {
                const uint8_t *p = pixels + (y * w + x) * channels;
                c0 = table[p[0]];
                c1 = table[p[1]];
                c2 = table[p[2]];
                float total = c0 + c1 + c2;
                if (total > scale_limit) outside += 1.0;
                if (total > 1.0f) {
                    c0 = c0 / total;
                    c1 = c1 / total;
                    c2 = c2 / total;
                }
                sum0 += c0;
                sum1 += c1;
                sum2 += c2;
            } else {
                const float *c = coverage + (y * w + x) * 3;
                c0 = c[0];
                c1 = c[1];
                c2 = c[2];
            }
            double v0 = (double)c0 + row[xe * 3 + 0];
            double v1 = (double)c1 + row[xe * 3 + 1];
            double v2 = (double)c2 + row[xe * 3 + 2];
            double best = v0;
            uint8_t label = 1;
            if (v1 > best) { best = v1; label = 2; }
            if (v2 > best) { best = v2; label = 3; }
            if (!(best > 0.5)) label = 0;
            labels[y * w + x] = label;
            double e0 = v0 - (label == 1 ? 1.0 : 0.0);
            double e1 = v1 - (label == 2 ? 1.0 : 0.0);
            double e2 = v2 - (label == 3 ? 1.0 : 0.0);
            for (Py_ssize_t t = 0; t < n; t++) {
                double *target = err + ring[t] * stride + (xe + offset[t]) * 3;
                double wk = wt[t];
                target[0] += e0 * wk;
                target[1] += e1 * wk;
                target[2] += e2 * wk;
            }
        }
        memset(row, 0, (size_t)stride * sizeof(double));
    }
    Py_END_ALLOW_THREADS

    stats[0] = outside;
    stats[1] = sum0;
    stats[2] = sum1;
    stats[3] = sum2;
    PyMem_Free(err); PyMem_Free(ring); PyMem_Free(offset);
    PyBuffer_Release(&cov); PyBuffer_Release(&pix); PyBuffer_Release(&tab);
    PyBuffer_Release(&bdy); PyBuffer_Release(&bdx); PyBuffer_Release(&bwt);
    PyBuffer_Release(&blab); PyBuffer_Release(&bst);
    Py_RETURN_NONE;
}

static PyMethodDef methods[] = {
    {"run", run, METH_VARARGS, "Vector error diffusion (see diffusion.py)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_diffuse",
                                    "The C build of the error-diffusion kernel.", -1,
                                    methods};

PyMODINIT_FUNC PyInit__diffuse(void) { return PyModule_Create(&module); }
