// One zstd compression and one decompression context per thread, reused across calls (creating a
// context costs far more than compressing a 33 KB tile). Shared by everything in a process that
// inflates zstd (archive sections, the cooker's GeoTIFF block reader). No sticky parameter or
// dictionary is ever set on the decompression context; compression parameters are set per call.
#pragma once

typedef struct ZSTD_CCtx_s ZSTD_CCtx;  // as zstd.h declares them: no zstd.h for includers
typedef struct ZSTD_DCtx_s ZSTD_DCtx;

namespace terrain::detail {

ZSTD_CCtx* thread_cctx();
ZSTD_DCtx* thread_dctx();

}  // namespace terrain::detail
