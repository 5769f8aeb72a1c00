/* libFuzzer target for the LAZ reader (LAS with compressed point data: the
 * LAS reader hands it to src/io/laz.c). The seeds in corpus/laz/ are small
 * LAZ and COPC files of every compressor and point format family, and
 * broken ones (cut chunks, a chunk table outside the file, an unknown
 * compressor, layer sizes past the chunk, an absurd point count). */
#include "fuzz_reader.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    return fuzz_reader(data, size, TESSEL_FORMAT_LAS);
}
