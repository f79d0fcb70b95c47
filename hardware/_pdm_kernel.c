/* Bit-level PDM decoding kernels for hardware.pdm (a CPython extension, no numpy C API).
 *
 * transpose(words, out, stride, offset)
 *     Tick words (uint32, bit k = channel k) -> one byte stream per channel:
 *     out[c * stride + offset + j] holds ticks 8j .. 8j+7 of channel c, tick 8j+s in bit s.
 *     len(words) must be a multiple of 8.
 *
 * lut_fir(streams, stride, rows, table, n_pos, row_pad, step, n_groups, out)
 *     The FIR by table look-up: output group g (8 consecutive decimated samples) of
 *     stream row r is  sum_q table[q, streams[r * stride + step * g + q], 0:8],  q < n_pos.
 *     table is float32 (n_pos, row_pad, 8) with n_pos a multiple of 4; out is float32
 *     (len(rows), n_groups * 8).  The table rows are padded (row_pad > 256) so that the
 *     four positions read together do not map to the same cache sets.
 *
 * sigma_delta(x, out)
 *     Second-order sigma-delta modulation of float64 rows x (C, N) into bits out (C, N)
 *     uint8: y = sign(v2) (+1 at 0); v1 += x - y; v2 += v1 - y; bit = y > 0.  The same
 *     double-precision operations in the same order as hardware.pdm's numpy loop.
 *
 * An AVX2 path is chosen at run time where the CPU has it; the portable path (forced by a
 * last argument portable=True, for the tests) gives the same sums in the same order.
 */
#define PY_SSIZE_T_CLEAN
#include <Python.h>
#include <stdint.h>
#include <string.h>

#if (defined(__x86_64__) || defined(__i386__)) && defined(__GNUC__)
#define HAVE_X86 1
#include <immintrin.h>
#endif

/* ---- transpose ------------------------------------------------------------------- */

static void transpose_portable(const uint32_t *w, Py_ssize_t n8, uint8_t *out,
                               Py_ssize_t stride) {
    for (Py_ssize_t j = 0; j < n8; j++) {
        for (int k = 0; k < 4; k++) {
            /* 8x8 bit matrix: byte s = channels 8k..8k+7 at tick s */
            uint64_t x = 0, t;
            for (int s = 0; s < 8; s++) x |= (uint64_t)((w[8 * j + s] >> (8 * k)) & 0xFF) << (8 * s);
            t = (x ^ (x >> 7)) & 0x00AA00AA00AA00AAULL;
            x ^= t ^ (t << 7);
            t = (x ^ (x >> 14)) & 0x0000CCCC0000CCCCULL;
            x ^= t ^ (t << 14);
            t = (x ^ (x >> 28)) & 0x00000000F0F0F0F0ULL;
            x ^= t ^ (t << 28);
            for (int i = 0; i < 8; i++) out[(8 * k + i) * stride + j] = (uint8_t)(x >> (8 * i));
        }
    }
}

#ifdef HAVE_X86
__attribute__((target("avx2"))) static void transpose_avx2(const uint32_t *w, Py_ssize_t n8,
                                                           uint8_t *out, Py_ssize_t stride) {
    /* per 128-bit lane: 4 ticks x 4 bytes -> 4 bytes x 4 ticks; the dword permutation then
       makes qword b of a register byte b of its 8 ticks */
    const __m256i shuf = _mm256_setr_epi8(0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15,
                                          0, 4, 8, 12, 1, 5, 9, 13, 2, 6, 10, 14, 3, 7, 11, 15);
    const __m256i perm = _mm256_setr_epi32(0, 4, 1, 5, 2, 6, 3, 7);
    Py_ssize_t j = 0;
    /* 32 ticks at a time: a 4x4 qword transpose gives register b = byte b of 32 ticks, and
       each movemask (bit 7 of every byte) is 32 ticks of one channel: one 4-byte store */
    for (; j + 4 <= n8; j += 4) {
        __m256i v[4], r[4];
        for (int i = 0; i < 4; i++) {
            v[i] = _mm256_loadu_si256((const __m256i *)(w + 8 * (j + i)));
            v[i] = _mm256_permutevar8x32_epi32(_mm256_shuffle_epi8(v[i], shuf), perm);
        }
        __m256i t0 = _mm256_unpacklo_epi64(v[0], v[1]), t1 = _mm256_unpackhi_epi64(v[0], v[1]);
        __m256i t2 = _mm256_unpacklo_epi64(v[2], v[3]), t3 = _mm256_unpackhi_epi64(v[2], v[3]);
        r[0] = _mm256_permute2x128_si256(t0, t2, 0x20);
        r[1] = _mm256_permute2x128_si256(t1, t3, 0x20);
        r[2] = _mm256_permute2x128_si256(t0, t2, 0x31);
        r[3] = _mm256_permute2x128_si256(t1, t3, 0x31);
        for (int b = 0; b < 4; b++) {
            __m256i x = r[b];
            for (int bit = 7; bit >= 0; bit--) {
                uint32_t m = (uint32_t)_mm256_movemask_epi8(x);
                memcpy(out + (8 * b + bit) * stride + j, &m, 4);
                x = _mm256_add_epi8(x, x);
            }
        }
    }
    for (; j < n8; j++) { /* the last few bytes: 8 ticks at a time */
        __m256i x = _mm256_loadu_si256((const __m256i *)(w + 8 * j));
        x = _mm256_permutevar8x32_epi32(_mm256_shuffle_epi8(x, shuf), perm);
        for (int bit = 7; bit >= 0; bit--) {
            uint32_t m = (uint32_t)_mm256_movemask_epi8(x);
            for (int b = 0; b < 4; b++) out[(8 * b + bit) * stride + j] = (uint8_t)(m >> (8 * b));
            x = _mm256_add_epi8(x, x);
        }
    }
}
#endif

/* ---- table look-up FIR ------------------------------------------------------------ */

static void lut_portable(const uint8_t *b, const float *T, Py_ssize_t n_pos, Py_ssize_t pad,
                         Py_ssize_t step, Py_ssize_t n_groups, float *o) {
    for (Py_ssize_t g = 0; g < n_groups * 8; g++) o[g] = 0.0f;
    for (Py_ssize_t q0 = 0; q0 < n_pos; q0 += 4) {
        const float *T0 = T + q0 * pad * 8;
        for (Py_ssize_t g = 0; g < n_groups; g++) {
            const uint8_t *bg = b + step * g + q0;
            const float *r0 = T0 + bg[0] * 8, *r1 = T0 + (pad + bg[1]) * 8;
            const float *r2 = T0 + (2 * pad + bg[2]) * 8, *r3 = T0 + (3 * pad + bg[3]) * 8;
            for (int i = 0; i < 8; i++) o[8 * g + i] += (r0[i] + r1[i]) + (r2[i] + r3[i]);
        }
    }
}

#ifdef HAVE_X86
__attribute__((target("avx2"))) static void lut_avx2(const uint8_t *b, const float *T,
                                                     Py_ssize_t n_pos, Py_ssize_t pad,
                                                     Py_ssize_t step, Py_ssize_t n_groups,
                                                     float *o) {
    /* four table positions at a time (their 4 x row_pad x 32 bytes stay in L1) over all
       groups; the partial sums live in out */
    for (Py_ssize_t g = 0; g < n_groups; g++) _mm256_storeu_ps(o + 8 * g, _mm256_setzero_ps());
    for (Py_ssize_t q0 = 0; q0 < n_pos; q0 += 4) {
        const float *T0 = T + q0 * pad * 8, *T1 = T0 + pad * 8;
        const float *T2 = T1 + pad * 8, *T3 = T2 + pad * 8;
        for (Py_ssize_t g = 0; g < n_groups; g++) {
            uint32_t w;
            memcpy(&w, b + step * g + q0, 4);
            __m256 a = _mm256_add_ps(_mm256_loadu_ps(T0 + (w & 255) * 8),
                                     _mm256_loadu_ps(T1 + ((w >> 8) & 255) * 8));
            __m256 c = _mm256_add_ps(_mm256_loadu_ps(T2 + ((w >> 16) & 255) * 8),
                                     _mm256_loadu_ps(T3 + (w >> 24) * 8));
            _mm256_storeu_ps(o + 8 * g, _mm256_add_ps(_mm256_loadu_ps(o + 8 * g), _mm256_add_ps(a, c)));
        }
    }
}
#endif

static int have_avx2(void) {
#ifdef HAVE_X86
    static int cached = -1;
    if (cached < 0) {
        __builtin_cpu_init();
        cached = __builtin_cpu_supports("avx2") ? 1 : 0;
    }
    return cached;
#else
    return 0;
#endif
}

/* ---- Python bindings -------------------------------------------------------------- */

static PyObject *py_transpose(PyObject *self, PyObject *args) {
    Py_buffer words, out;
    Py_ssize_t stride, offset;
    int portable = 0;
    if (!PyArg_ParseTuple(args, "y*w*nn|p", &words, &out, &stride, &offset, &portable)) return NULL;
    PyObject *result = NULL;
    Py_ssize_t n8 = words.len / 32;
    if (words.len % 32 != 0) {
        PyErr_Format(PyExc_ValueError, "transpose: %zd bytes of tick words is not a multiple of 32",
                     words.len);
    } else if (offset < 0 || offset + n8 > stride || 32 * stride > out.len) {
        PyErr_Format(PyExc_ValueError, "transpose: output of %zd bytes, stride %zd, offset %zd is too small for %zd bytes per channel",
                     out.len, stride, offset, n8);
    } else {
        Py_BEGIN_ALLOW_THREADS
#ifdef HAVE_X86
        if (!portable && have_avx2())
            transpose_avx2((const uint32_t *)words.buf, n8, (uint8_t *)out.buf + offset, stride);
        else
#endif
            transpose_portable((const uint32_t *)words.buf, n8, (uint8_t *)out.buf + offset, stride);
        Py_END_ALLOW_THREADS
        result = Py_None;
        Py_INCREF(result);
    }
    PyBuffer_Release(&words);
    PyBuffer_Release(&out);
    return result;
}

static PyObject *py_lut_fir(PyObject *self, PyObject *args) {
    Py_buffer streams, rows, table, out;
    Py_ssize_t stride, n_pos, pad, step, n_groups;
    int portable = 0;
    if (!PyArg_ParseTuple(args, "y*ny*y*nnnnw*|p", &streams, &stride, &rows, &table, &n_pos, &pad,
                          &step, &n_groups, &out, &portable))
        return NULL;
    PyObject *result = NULL;
    Py_ssize_t n_rows = rows.len / (Py_ssize_t)sizeof(int32_t);
    const int32_t *r = (const int32_t *)rows.buf;
    int ok = n_pos % 4 == 0 && pad >= 256 && table.len >= n_pos * pad * 8 * 4 &&
             out.len >= n_rows * n_groups * 8 * 4 && step * (n_groups - 1) + n_pos <= stride;
    for (Py_ssize_t i = 0; ok && i < n_rows; i++) ok = r[i] >= 0 && (r[i] + 1) * stride <= streams.len;
    if (!ok) {
        PyErr_SetString(PyExc_ValueError, "lut_fir: inconsistent sizes of streams, rows, table or out");
    } else {
        const uint8_t *b = (const uint8_t *)streams.buf;
        const float *T = (const float *)table.buf;
        float *o = (float *)out.buf;
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t i = 0; i < n_rows; i++) {
#ifdef HAVE_X86
            if (!portable && have_avx2())
                lut_avx2(b + r[i] * stride, T, n_pos, pad, step, n_groups, o + i * n_groups * 8);
            else
#endif
                lut_portable(b + r[i] * stride, T, n_pos, pad, step, n_groups, o + i * n_groups * 8);
        }
        Py_END_ALLOW_THREADS
        result = Py_None;
        Py_INCREF(result);
    }
    PyBuffer_Release(&streams);
    PyBuffer_Release(&rows);
    PyBuffer_Release(&table);
    PyBuffer_Release(&out);
    return result;
}

static PyObject *py_sigma_delta(PyObject *self, PyObject *args) {
    Py_buffer x, out;
    Py_ssize_t n;
    if (!PyArg_ParseTuple(args, "y*w*n", &x, &out, &n)) return NULL;
    PyObject *result = NULL;
    if (n <= 0 || x.len % (n * (Py_ssize_t)sizeof(double)) != 0 ||
        out.len != x.len / (Py_ssize_t)sizeof(double)) {
        PyErr_SetString(PyExc_ValueError, "sigma_delta: x must be float64 (C, n), out uint8 (C, n)");
    } else {
        const double *xs = (const double *)x.buf;
        uint8_t *o = (uint8_t *)out.buf;
        Py_ssize_t rows = x.len / (n * (Py_ssize_t)sizeof(double));
        Py_BEGIN_ALLOW_THREADS
        for (Py_ssize_t c = 0; c < rows; c++) {
            double v1 = 0.0, v2 = 0.0;
            for (Py_ssize_t t = 0; t < n; t++) {
                double y = v2 >= 0.0 ? 1.0 : -1.0;
                o[c * n + t] = y > 0.0;
                v1 += xs[c * n + t] - y;
                v2 += v1 - y;
            }
        }
        Py_END_ALLOW_THREADS
        result = Py_None;
        Py_INCREF(result);
    }
    PyBuffer_Release(&x);
    PyBuffer_Release(&out);
    return result;
}

static PyObject *py_simd(PyObject *self, PyObject *noargs) {
    return PyUnicode_FromString(have_avx2() ? "avx2" : "portable");
}

static PyMethodDef methods[] = {
    {"transpose", py_transpose, METH_VARARGS, "Tick words -> one byte stream per channel."},
    {"lut_fir", py_lut_fir, METH_VARARGS, "FIR and decimation by table look-up on byte streams."},
    {"sigma_delta", py_sigma_delta, METH_VARARGS, "Second-order sigma-delta modulation."},
    {"simd", py_simd, METH_NOARGS, "The instruction set the kernels use on this CPU."},
    {NULL, NULL, 0, NULL},
};

static struct PyModuleDef module = {PyModuleDef_HEAD_INIT, "_pdm_kernel",
                                    "Bit-level PDM decoding kernels (see hardware.pdm).", -1,
                                    methods};

PyMODINIT_FUNC PyInit__pdm_kernel(void) { return PyModule_Create(&module); }
