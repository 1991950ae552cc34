// One zstd compression and one decompression context per thread, reused across calls
// (creating a context costs far more than compressing a 33 KB tile).
#pragma once
#include <zstd.h>

namespace terrain::detail {

ZSTD_CCtx* thread_cctx();
ZSTD_DCtx* thread_dctx();

}  // namespace terrain::detail
