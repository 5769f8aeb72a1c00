#!/bin/sh
# Builds the tests that run flips and checks on several threads with
# ThreadSanitizer (clang) and runs them on two threads; any race report
# fails. Where ThreadSanitizer cannot run at all (a kernel whose address
# layout it does not support), says so and skips.
# Usage: tsan.sh BUILD_DIR
set -eu
build=$1
archer=$(ls /usr/lib/llvm-*/lib/libarcher.so 2>/dev/null | head -n 1 || true)
probe=$(mktemp -d)
trap 'rm -rf "$probe"' EXIT
printf 'int main(void) { return 0; }\n' >"$probe/p.c"
if ! clang -fsanitize=thread "$probe/p.c" -o "$probe/p" 2>/dev/null || ! "$probe/p"; then
    echo "ThreadSanitizer does not run on this machine: skipped"
    exit 0
fi
if [ -z "$archer" ]; then
    echo "no libarcher.so (libomp-dev): skipped"
    exit 0
fi
CC=clang cmake -S . -B "$build" -DCMAKE_BUILD_TYPE=RelWithDebInfo \
    -DCMAKE_C_FLAGS="-fsanitize=thread -DTESSEL_NO_CLONES" \
    -DCMAKE_EXE_LINKER_FLAGS=-fsanitize=thread -DTESSEL_BENCH=OFF >/dev/null
cmake --build "$build" -j "$(nproc)" --target test_refine test_orient test_greedy >/dev/null
for t in test_refine test_orient test_greedy; do
    echo "$t"
    OMP_NUM_THREADS=2 OMP_TOOL_LIBRARIES="$archer" \
        TSAN_OPTIONS="ignore_noninstrumented_modules=1 halt_on_error=1" \
        "$build/tests/$t" >"$build/$t.log" 2>&1 || { tail -60 "$build/$t.log"; exit 1; }
done
