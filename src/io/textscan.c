/* Number scanning and formatting for the text formats.
 *
 * Scanning is bounded by an end pointer (input buffers need not be
 * NUL-terminated at the token) and ignores the C locale: '.' is the only
 * decimal point. Doubles take Clinger's fast path (W. D. Clinger, "How to
 * read floating point numbers accurately", PLDI 1990, section 5): when the
 * decimal significand fits in 53 bits and the power of ten is at most 22,
 * one IEEE multiplication or division is correctly rounded. Other numbers
 * are rewritten as "DIGITSe+N" (no decimal point, so no locale) and given to
 * strtod, which glibc and musl round correctly.
 *
 * Formatting writes the shortest text that reads back, through the same
 * scanner and the builder's rounding, to the same float and offset. */
#include "io/io.h"

#include <float.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const double pow10_exact[23] = {
    1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
    1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};

/* Significant digits kept for strtod: more than the 767 that can matter for
 * a double; the rest only tells "non-zero" through a sticky digit. */
#define MAX_DIGITS 800
/* Exponents saturate here: far past the double range either way. */
#define EXP_SATURATE 100000

static bool is_digit(char c) { return c >= '0' && c <= '9'; }

static char lower(char c) { return (c >= 'A' && c <= 'Z') ? (char)(c - 'A' + 'a') : c; }

/* Case-insensitive match of word at s; returns its length or 0. */
static size_t match_word(const char *s, const char *end, const char *word)
{
    size_t n = strlen(word);
    if ((size_t)(end - s) < n)
        return 0;
    for (size_t i = 0; i < n; i++)
        if (lower(s[i]) != word[i])
            return 0;
    return n;
}

/* Slow, exact path: the token's digits without leading zeros, then the
 * adjusted exponent, handed to strtod. */
static double slow_parse(const char *s, const char *end, bool neg, long exp10)
{
    char buf[MAX_DIGITS + 32];
    size_t n = 0;
    bool sticky = false, seen_point = false;
    long e = exp10;
    if (neg)
        buf[n++] = '-';
    size_t first = n;
    for (; s < end; s++) {
        if (*s == '.') {
            seen_point = true;
            continue;
        }
        if (!is_digit(*s))
            break;
        bool leading = (n == first && *s == '0');
        if (leading) {
            if (seen_point)
                e--;
            continue;
        }
        if (n - first < MAX_DIGITS) {
            buf[n++] = *s;
            if (seen_point)
                e--;
        } else {
            if (*s != '0')
                sticky = true;
            if (!seen_point)
                e++;
        }
    }
    if (n == first)
        return neg ? -0.0 : 0.0;
    if (sticky) {
        buf[n++] = '1';
        e--;
    }
    snprintf(buf + n, sizeof buf - n, "e%ld", e);
    return strtod(buf, NULL);
}

bool tsl_scan_double(const char **p, const char *end, double *out)
{
    const char *s = tsl_skip_blanks(*p, end);
    bool neg = false;
    if (s < end && (*s == '+' || *s == '-')) {
        neg = (*s == '-');
        s++;
    }
    if (s < end && !is_digit(*s) && *s != '.') {
        size_t n;
        if ((n = match_word(s, end, "infinity")) || (n = match_word(s, end, "inf"))) {
            *out = neg ? -INFINITY : INFINITY;
            *p = s + n;
            return true;
        }
        if ((n = match_word(s, end, "nan"))) {
            s += n;
            /* nan(chars), as printf may write it */
            if (s < end && *s == '(') {
                const char *q = s + 1;
                while (q < end && (is_digit(*q) || (lower(*q) >= 'a' && lower(*q) <= 'z') ||
                                   *q == '_'))
                    q++;
                if (q < end && *q == ')')
                    s = q + 1;
            }
            *out = neg ? -NAN : NAN;
            *p = s;
            return true;
        }
        return false;
    }
    const char *digits = s;
    uint64_t m = 0;
    int nd = 0;            /* significant digits accumulated in m */
    bool truncated = false;
    bool any = false;
    long exp10 = 0;
    while (s < end && is_digit(*s)) {
        int d = *s - '0';
        any = true;
        if (m == 0 && d == 0) {
            /* leading zero */
        } else if (nd < 19) {
            m = m * 10 + (uint64_t)d;
            nd++;
        } else {
            truncated = true;
            exp10++;
        }
        s++;
    }
    if (s < end && *s == '.') {
        s++;
        while (s < end && is_digit(*s)) {
            int d = *s - '0';
            any = true;
            if (m == 0 && d == 0) {
                exp10--;
            } else if (nd < 19) {
                m = m * 10 + (uint64_t)d;
                nd++;
                exp10--;
            } else {
                truncated = true;
            }
            s++;
        }
    }
    if (!any)
        return false;
    const char *mant_end = s;
    long e = 0;
    if (s < end && (*s == 'e' || *s == 'E')) {
        const char *q = s + 1;
        bool eneg = false;
        if (q < end && (*q == '+' || *q == '-')) {
            eneg = (*q == '-');
            q++;
        }
        if (q < end && is_digit(*q)) {
            while (q < end && is_digit(*q)) {
                if (e < EXP_SATURATE)
                    e = e * 10 + (*q - '0');
                q++;
            }
            if (eneg)
                e = -e;
            s = q;
        }
        /* "1e" or "1e+" : the number ends before the 'e', as in strtod */
    }
    *p = s;
    if (m == 0) {
        *out = neg ? -0.0 : 0.0;
        return true;
    }
    long total = exp10 + e;
    if (!truncated && m <= ((uint64_t)1 << 53) && total >= -22 && total <= 22) {
        double v = (double)m;
        v = total >= 0 ? v * pow10_exact[total] : v / pow10_exact[-total];
        *out = neg ? -v : v;
        return true;
    }
    *out = slow_parse(digits, mant_end, neg, e);
    return true;
}

bool tsl_scan_u64(const char **p, const char *end, uint64_t *out)
{
    const char *s = tsl_skip_blanks(*p, end);
    if (s < end && *s == '+')
        s++;
    if (s >= end || !is_digit(*s))
        return false;
    uint64_t v = 0;
    while (s < end && is_digit(*s)) {
        uint64_t d = (uint64_t)(*s - '0');
        if (v > (UINT64_MAX - d) / 10)
            return false;
        v = v * 10 + d;
        s++;
    }
    *out = v;
    *p = s;
    return true;
}

bool tsl_scan_i64(const char **p, const char *end, int64_t *out)
{
    const char *s = tsl_skip_blanks(*p, end);
    bool neg = false;
    if (s < end && (*s == '+' || *s == '-')) {
        neg = (*s == '-');
        s++;
    }
    if (s >= end || !is_digit(*s))
        return false;
    uint64_t mag;
    if (!tsl_scan_u64(&s, end, &mag))
        return false;
    if (neg) {
        if (mag > (uint64_t)INT64_MAX + 1)
            return false;
        *out = mag == (uint64_t)INT64_MAX + 1 ? INT64_MIN : -(int64_t)mag;
    } else {
        if (mag > (uint64_t)INT64_MAX)
            return false;
        *out = (int64_t)mag;
    }
    *p = s;
    return true;
}

/* ---- formatting ---- */

/* printf honours LC_NUMERIC; put back a '.' if a locale changed it. */
static int fix_decimal_point(char *buf, int len)
{
    for (int i = 0; i < len; i++) {
        char c = buf[i];
        if (is_digit(c) || c == '-' || c == '+' || c == 'e' || c == '.')
            continue;
        int j = i;
        while (j < len && !is_digit(buf[j]) && buf[j] != 'e')
            j++;
        buf[i] = '.';
        memmove(buf + i + 1, buf + j, (size_t)(len - j) + 1);
        return len - (j - i - 1);
    }
    return len;
}

/* Whether text reads back to float f with offset: same integer part of the
 * world coordinate (what the offset rule sees) and the same float. */
static bool reads_back(const char *buf, int len, double offset, float f)
{
    const char *p = buf;
    double v;
    if (!tsl_scan_double(&p, buf + len, &v) || p != buf + len)
        return false;
    return floor(v) == floor(offset + (double)f) && tsl_local_coord(v, offset) == f;
}

int tsl_format_coord(char *buf, double offset, float f)
{
    int len;
    if (isnan(f))
        return snprintf(buf, 32, "nan");
    if (isinf(f))
        return snprintf(buf, 32, f < 0 ? "-inf" : "inf");
    if (offset == 0.0) {
        for (int prec = 7; prec <= 9; prec++) {
            len = fix_decimal_point(buf, snprintf(buf, 32, "%.*g", prec, (double)f));
            if (reads_back(buf, len, 0.0, f))
                return len;
        }
        return fix_decimal_point(buf, snprintf(buf, 32, "%.17g", (double)f));
    }
    double w = offset + (double)f; /* exact for floats from tsl_local_coord */
    if (fabs(w) < 1e15) {
        /* Enough decimals to land within a quarter ulp of f. */
        double ulp = (double)nextafterf(fabsf(f), INFINITY) - (double)fabsf(f);
        int places = (int)ceil(log10(2.0 / ulp));
        if (places < 0)
            places = 0;
        for (int k = 0; k < 3 && places + k <= 17; k++) {
            int r = snprintf(buf, 32, "%.*f", places + k, w);
            if (r < 0 || r >= 32)
                break;
            len = fix_decimal_point(buf, r);
            /* Trailing zeros say nothing: "500000.25", not "500000.25000000". */
            if (memchr(buf, '.', (size_t)len)) {
                while (buf[len - 1] == '0')
                    len--;
                if (buf[len - 1] == '.')
                    len--;
                buf[len] = 0;
            }
            if (reads_back(buf, len, offset, f))
                return len;
        }
    }
    return fix_decimal_point(buf, snprintf(buf, 32, "%.17g", w));
}
