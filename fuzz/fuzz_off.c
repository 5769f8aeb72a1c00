/* libFuzzer target for the OFF reader. */
#include "fuzz_reader.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_reader(data, size, TESSEL_FORMAT_OFF);
}
