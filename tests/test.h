/* A tiny test harness: CHECK records a failure and goes on; main() ends
 * with TEST_SUMMARY(), which prints "N passed, N failed" and returns the exit
 * code. Each test file is one executable run by ctest. */
#ifndef TESSEL_TEST_H
#define TESSEL_TEST_H

#include <stdio.h>

static int test_passed_count, test_failed_count;

#define CHECK(cond)                                                            \
    do {                                                                       \
        if (cond) {                                                            \
            test_passed_count++;                                               \
        } else {                                                               \
            test_failed_count++;                                               \
            fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__,   \
                    #cond);                                                    \
        }                                                                      \
    } while (0)

#define CHECK_MSG(cond, ...)                                                   \
    do {                                                                       \
        if (cond) {                                                            \
            test_passed_count++;                                               \
        } else {                                                               \
            test_failed_count++;                                               \
            fprintf(stderr, "%s:%d: check failed: %s: ", __FILE__, __LINE__,    \
                    #cond);                                                    \
            fprintf(stderr, __VA_ARGS__);                                      \
            fputc('\n', stderr);                                               \
        }                                                                      \
    } while (0)

#define TEST_SUMMARY()                                                         \
    (printf("%d passed, %d failed\n", test_passed_count, test_failed_count),   \
     test_failed_count ? 1 : 0)

#endif
