/* Environment light through a material's lobes: the C build of env_model._block_xyz, per
 * pixel in one pass (the numpy build gathers each level's texels over every pixel in turn).
 *
 * Why C: the sum reads ≤ 6 bilinear texels per lobe and pixel; numpy spends its time on
 * temporaries and per-level passes (150-200 ms for a 512² clear-coated sphere), and numba's
 * import and the loading of its cached kernel (~0.7-1 s in a fresh process) cost more than
 * the whole render. This module is built by pip when gonio is installed (a C compiler and the
 * Python headers, as _diffuse.c); where it could not be built, env_model.py uses numpy. The
 * two agree to ~2e-4 of the largest value (float32 maps; the angles to 1e-5 rad, fast_atan2):
 * tests/test_env_model.py compares them.
 *
 * Per pixel (env_model's module docstring has the equations): θv = acos(N·V) and its view
 * row i0 and weight t (linear in θv over view_deg); the tangent T towards R; per lobe k its
 * axis d = cos β N + sin β T (cos β and sin β interpolated in θv: within ~(Δβ)²/8 of the
 * interpolated β, 3e-4 rad for a step Δβ = 0.05 between rows), the mixture Σ_l w_kl P_l(d) of the
 * chain's levels (w interpolated in θv, levels whose weight is 0 at both rows skipped), and
 * its colour: out += p · ((1 − t) M_k[i0] + t M_k[i0 + 1]).
 *
 * Interface (checked by env_model.py before the call; buffers C-contiguous):
 *   run(normal, view, n, start, stop, view_deg, n_view, cos_beta, sin_beta, weights, matrices,
 *       n_lobes, maps, heights, widths, n_levels, channels, out) -> None
 *   normal, view float32 (3, n)       unit N and V, one row per component (the G-buffer's
 *                                     layout: no copy); pixels start … stop − 1 are done
 *   view_deg     float64 (V,)         the tables' view angles, increasing
 *   cos_beta, sin_beta float64 (K, V) cosine and sine of the axis tilt β
 *   weights      float64 (K, V, L)    level weights
 *   matrices     float64 (K, V, 3, C) rgb -> output channels
 *   maps         tuple of L objects   float32 (H_l, W_l, 3) maps, or None for unused levels
 *   heights, widths int64 (L,)
 *   out          float64 (n, C)       added to (rows start … stop − 1)
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <math.h>
#include <stdint.h>

#define MAX_LEVELS 64
#define MAX_LOBES 16

/* atan2(y, x) in [−π, π] to 1e-5 rad (the lookups' angles; a texel of the sharpest 1024-wide
 * map is 6e-3 rad, so 0.2 % of one): Abramowitz & Stegun 4.4.47, atan r = Σ a_2k+1 r^2k+1
 * on 0 ≤ r ≤ 1, |ε| ≤ 1e-5, folded to the octants. libm's atan2 and acos were 70 % of the
 * kernel's time; 4.4.49's 2e-8 rad (nine terms) cost 8 % more of it than these five. */
static double fast_atan2(double y, double x) {
    double ax = fabs(x), ay = fabs(y);
    double hi = ax > ay ? ax : ay, lo = ax > ay ? ay : ax;
    if (hi == 0.0) return 0.0;
    double r = lo / hi, r2 = r * r;
    double a = r * (0.9998660 + r2 * (-0.3302995 + r2 * (0.1801410 + r2 * (-0.0851330
               + r2 * 0.0208351))));
    if (ay > ax) a = M_PI / 2 - a;
    if (x < 0.0) a = M_PI - a;
    return y < 0.0 ? -a : a;
}

typedef struct {
    const float *texels;
    int64_t h, w;
    double row_scale, col_scale;                     /* h / π and w / 2π */
} Map;

/* Where a direction (θ, φ) falls on a map of h × w texels: its 2 × 2 texels' offsets and
 * the bilinear weights; levels of the same size share it (the sharp levels of a chain). */
typedef struct {
    int64_t h, w;                                    /* the size it was computed for */
    int64_t a, b, c, d;                              /* float offsets of the four texels */
    float fr, fc;
} Footprint;

static void footprint(const Map *m, double theta, double phi, Footprint *f) {
    int64_t h = m->h, w = m->w;
    double row = theta * m->row_scale - 0.5;
    double col = phi * m->col_scale - 0.5;           /* φ in [0, 2π): col in [−0.5, w − 0.5) */
    if (row < 0.0) row = 0.0;
    if (row > (double)(h - 1)) row = (double)(h - 1);
    int64_t r0 = (int64_t)row;
    int64_t c0 = col < 0.0 ? -1 : (int64_t)col;     /* floor */
    f->fr = (float)(row - (double)r0);
    f->fc = (float)(col - (double)c0);
    int64_t r1 = r0 + 1 < h ? r0 + 1 : h - 1;
    if (c0 < 0) c0 += w;                             /* φ wraps */
    if (c0 >= w) c0 -= w;
    int64_t c1 = c0 + 1 < w ? c0 + 1 : 0;
    f->h = h;
    f->w = w;
    f->a = 3 * (r0 * w + c0);
    f->b = 3 * (r0 * w + c1);
    f->c = 3 * (r1 * w + c0);
    f->d = 3 * (r1 * w + c1);
}

/* p += weight × the map's bilinear value at the footprint (computed anew unless its size
 * is the footprint's). */
static void bilinear_add(const Map *m, double theta, double phi, Footprint *f, double weight,
                         double *p) {
    if (f->h != m->h || f->w != m->w) footprint(m, theta, phi, f);
    const float *img = m->texels;
    const float *a = img + f->a, *b = img + f->b, *c = img + f->c, *d = img + f->d;
    for (int j = 0; j < 3; j++) {
        float top = a[j] + f->fc * (b[j] - a[j]);
        float bottom = c[j] + f->fc * (d[j] - c[j]);
        p[j] += weight * (double)(top + f->fr * (bottom - top));
    }
}

/* Row i0 (0 <= i0 <= V - 2) and weight t of linear interpolation of theta_deg over view_deg
 * (np.interp: clamped at both ends); ``first[d]`` is the last row with view_deg <= d degrees
 * (d = 0 … 90), so at most a step or two remain (no binary search's mispredicted branches). */
static void view_row(const double *view_deg, Py_ssize_t n_view, const Py_ssize_t *first,
                     double theta_deg, Py_ssize_t *i0, double *t) {
    if (n_view < 2) { *i0 = 0; *t = 0.0; return; }
    if (theta_deg <= view_deg[0]) { *i0 = 0; *t = 0.0; return; }
    if (theta_deg >= view_deg[n_view - 1]) { *i0 = n_view - 2; *t = 1.0; return; }
    Py_ssize_t lo = first[(int)theta_deg];          /* 0 <= θ < 90 here */
    while (lo + 1 < n_view - 1 && view_deg[lo + 1] <= theta_deg) lo++;
    *i0 = lo;
    *t = (theta_deg - view_deg[lo]) / (view_deg[lo + 1] - view_deg[lo]);
}

static void pixel(const double *nn, const double *vv, const double *view_deg, Py_ssize_t V,
                  const Py_ssize_t *first,
                  const double *cos_beta, const double *sin_beta, const double *weights, const double *matrices,
                  Py_ssize_t K, const Map *maps, const int64_t *used, const int64_t *n_used,
                  const int *at_normal,
                  Py_ssize_t L, Py_ssize_t C, double *out) {
    double cos_v = nn[0] * vv[0] + nn[1] * vv[1] + nn[2] * vv[2];
    cos_v = cos_v < 0.0 ? 0.0 : (cos_v > 1.0 ? 1.0 : cos_v);
    Py_ssize_t i0;
    double t;
    double sin_v = sqrt((1.0 - cos_v) * (1.0 + cos_v));
    view_row(view_deg, V, first, fast_atan2(sin_v, cos_v) * (180.0 / M_PI), &i0, &t);
    double tg[3], norm = 0.0;
    for (int j = 0; j < 3; j++) { tg[j] = cos_v * nn[j] - vv[j]; norm += tg[j] * tg[j]; }
    norm = sqrt(norm);
    for (int j = 0; j < 3; j++) tg[j] = norm > 1e-12 ? tg[j] / norm : 0.0;
    double theta_n = 0.0, phi_n = 0.0;
    int have_normal = 0;
    for (Py_ssize_t k = 0; k < K; k++) {
        const double *ck = cos_beta + k * V, *sk = sin_beta + k * V;
        double theta, phi;
        if (at_normal[k] && have_normal) {           /* a diffuse body: its axis is N */
            theta = theta_n;
            phi = phi_n;
        } else {
            double cb = ck[i0] + t * (ck[i0 + 1] - ck[i0]);
            double sb = sk[i0] + t * (sk[i0 + 1] - sk[i0]), d[3];
            for (int j = 0; j < 3; j++) d[j] = cb * nn[j] + sb * tg[j];
            /* θ = acos(d_y / |d|) = atan2(|d_xz|, d_y); a zero d is the zenith (θ = 0) */
            theta = fast_atan2(sqrt(d[0] * d[0] + d[2] * d[2]), d[1]);
            phi = fast_atan2(d[0], -d[2]);
            if (phi < 0.0) phi += 2.0 * M_PI;
            if (phi >= 2.0 * M_PI) phi = 0.0;
            if (at_normal[k]) { theta_n = theta; phi_n = phi; have_normal = 1; }
        }
        const double *w0 = weights + (k * V + i0) * L, *w1 = w0 + L;
        double p[3] = {0.0, 0.0, 0.0};
        Footprint f = {-1, -1, 0, 0, 0, 0, 0.0f, 0.0f};
        for (int64_t u = 0; u < n_used[k]; u++) {  /* the levels lobe k mixes somewhere */
            int64_t l = used[k * L + u];
            if (w0[l] <= 0.0 && w1[l] <= 0.0) continue;
            bilinear_add(&maps[l], theta, phi, &f, w0[l] + t * (w1[l] - w0[l]), p);
        }
        const double *m0 = matrices + (k * V + i0) * 3 * C, *m1 = m0 + 3 * C;
        for (Py_ssize_t j = 0; j < C; j++) {
            double s = 0.0;
            for (int c = 0; c < 3; c++)
                s += p[c] * (m0[c * C + j] + t * (m1[c * C + j] - m0[c * C + j]));
            out[j] += s;
        }
    }
}

static PyObject *run(PyObject *self, PyObject *args) {
    Py_buffer bn, bv, bdeg, bcb, bsb, bw, bm, bh, bws, bout;
    Py_ssize_t n, start, stop, V, K, L, C;
    PyObject *maps_tuple;
    if (!PyArg_ParseTuple(args, "y*y*nnny*ny*y*y*y*nO!y*y*nnw*", &bn, &bv, &n, &start, &stop,
                          &bdeg, &V, &bcb, &bsb, &bw, &bm, &K, &PyTuple_Type, &maps_tuple, &bh,
                          &bws, &L, &C, &bout))
        return NULL;
    Py_buffer bmaps[MAX_LEVELS];
    Map maps[MAX_LEVELS];
    int64_t used[MAX_LEVELS * MAX_LOBES], n_used[MAX_LOBES];
    int at_normal[MAX_LOBES];                        /* β = 0 at every view: the axis is N */
    Py_ssize_t got = 0;
    PyObject *result = NULL;
    if (L > MAX_LEVELS || K > MAX_LOBES
            || PyTuple_GET_SIZE(maps_tuple) != L) {
        PyErr_SetString(PyExc_ValueError, "_envlookup.run: bad level or channel count");
        goto done;
    }
    if (bn.len != (Py_ssize_t)(3 * n * sizeof(float)) || bv.len != bn.len
            || bout.len != (Py_ssize_t)(n * C * sizeof(double))
            || start < 0 || stop < start || stop > n) {
        PyErr_SetString(PyExc_ValueError, "_envlookup.run: buffer sizes or range do not match");
        goto done;
    }
    for (; got < L; got++) {
        PyObject *m = PyTuple_GET_ITEM(maps_tuple, got);
        const int64_t *hs = bh.buf, *ws = bws.buf;
        maps[got].texels = NULL;
        bmaps[got].obj = NULL;
        if (m == Py_None) continue;
        if (PyObject_GetBuffer(m, &bmaps[got], PyBUF_C_CONTIGUOUS) < 0) goto done;
        maps[got] = (Map){(const float *)bmaps[got].buf, hs[got], ws[got],
                          (double)hs[got] / M_PI, (double)ws[got] / (2.0 * M_PI)};
    }
    for (Py_ssize_t k = 0; k < K; k++) {             /* per lobe, the levels it ever mixes */
        const double *wk = (const double *)bw.buf + k * V * L;
        const double *sk = (const double *)bsb.buf + k * V;
        at_normal[k] = 1;
        for (Py_ssize_t r = 0; r < V; r++) at_normal[k] &= fabs(sk[r]) <= 1e-12;
        n_used[k] = 0;
        for (Py_ssize_t l = 0; l < L; l++) {
            int any = 0;
            for (Py_ssize_t r = 0; r < V; r++) any |= wk[r * L + l] > 0.0;
            if (!any) continue;
            if (maps[l].texels == NULL) {
                PyErr_SetString(PyExc_ValueError, "_envlookup.run: a used level has no map");
                goto done;
            }
            used[k * L + n_used[k]++] = l;
        }
    }
    Py_ssize_t first[91];
    for (int d = 0, r = 0; d <= 90; d++) {
        while (r + 1 < V && ((const double *)bdeg.buf)[r + 1] <= (double)d) r++;
        first[d] = r;
    }
    {
        const float *nn = bn.buf, *vv = bv.buf;
        const double *deg = bdeg.buf, *cb = bcb.buf;
        const double *sb = bsb.buf;
        const double *w = bw.buf, *mat = bm.buf;
        double *out = bout.buf;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t i = start; i < stop; i++) {
            double ni[3] = {nn[i], nn[n + i], nn[2 * n + i]};
            double vi[3] = {vv[i], vv[n + i], vv[2 * n + i]};
            pixel(ni, vi, deg, V, first, cb, sb, w, mat, K, maps, used, n_used, at_normal, L, C,
                  out + C * i);
        }
        Py_END_ALLOW_THREADS
    }
    result = Py_None;
    Py_INCREF(result);
done:
    for (Py_ssize_t l = 0; l < got; l++)
        if (bmaps[l].obj != NULL) PyBuffer_Release(&bmaps[l]);
    PyBuffer_Release(&bn); PyBuffer_Release(&bv); PyBuffer_Release(&bdeg);
    PyBuffer_Release(&bcb); PyBuffer_Release(&bsb); PyBuffer_Release(&bw); PyBuffer_Release(&bm);
    PyBuffer_Release(&bh); PyBuffer_Release(&bws); PyBuffer_Release(&bout);
    return result;
}

static PyMethodDef methods[] = {
    {"run", run, METH_VARARGS, "Environment light through a material's lobes (see header)."},
    {NULL, NULL, 0, NULL}};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_envlookup",
                                    "Environment lookups of env_model in C.", -1, methods};

PyMODINIT_FUNC PyInit__envlookup(void) { return PyModule_Create(&module); }
