#include "tcpest/hal/camera/jpeg_decoder.hpp"

#include <csetjmp>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <new>

// libjpeg's headers need <cstdio> first and are C.
extern "C" {
#include <jerror.h>
#include <jpeglib.h>
}

namespace tcpest {
namespace hal {

namespace {
constexpr std::size_t kAlign = 64U;          // libjpeg-turbo's SIMD wants 32; one cache line
constexpr std::size_t kFixedArenaBytes = std::size_t{256U} * 1024U;
constexpr std::size_t kMaxArenaBytes = std::size_t{256U} * 1024U * 1024U;  // an absurd request is refused
constexpr std::size_t kArenaRowsPerWidth = 64U;  // measured need is below ~40 RGB rows (README)
constexpr int kRowBatch = 16;                 // scanlines per jpeg_read_scanlines call

std::size_t round_up(std::size_t value, std::size_t multiple) noexcept {
  return (value + multiple - 1U) / multiple * multiple;
}
}  // namespace

struct JpegDecoder::Context {
  jpeg_decompress_struct cinfo{};
  jpeg_error_mgr jerr{};
  std::jmp_buf jump{};
  CameraError error = CameraError::kNone;
  char message[JMSG_LENGTH_MAX] = {};

  // The arena: permanent allocations grow up from the start, per-image ones
  // down from the end; the image part is reset before every decode.
  std::uint8_t* arena = nullptr;
  std::size_t capacity = 0U;
  std::size_t permanent_top = 0U;
  std::size_t image_bottom = 0U;
  std::size_t image_high_water = 0U;
  std::size_t fallback_decodes = 0U;
  int max_width = 0;
  int max_height = 0;

  // What one guarded step works on.
  const std::uint8_t* data = nullptr;
  std::size_t size = 0U;
  MutableImageView out{};
  JpegInfo info{};
};

namespace {

using Context = JpegDecoder::Context;

Context& context_of(j_common_ptr cinfo) noexcept { return *static_cast<Context*>(cinfo->client_data); }

CameraError map_message_code(int code) noexcept {
  switch (code) {
    case JERR_OUT_OF_MEMORY:
      return CameraError::kOutOfMemory;
    case JERR_CONVERSION_NOTIMPL:
    case JERR_NOT_COMPILED:
    case JERR_ARITH_NOTIMPL:
    case JERR_BAD_PRECISION:
      return CameraError::kUnsupported;
    case JERR_INPUT_EMPTY:
    case JERR_INPUT_EOF:
    case JWRN_JPEG_EOF:
      return CameraError::kTruncated;
    default:
      return CameraError::kCorrupt;
  }
}

// libjpeg's error_exit must not return: record the error and jump back to
// run_guarded(). Warnings (msg_level -1: corrupt data that libjpeg would patch
// over) take the same way; trace messages (level >= 0) are ignored.
[[noreturn]] void on_fatal(j_common_ptr cinfo) {
  Context& ctx = context_of(cinfo);
  ctx.error = map_message_code(cinfo->err->msg_code);
  (*cinfo->err->format_message)(cinfo, ctx.message);
  std::longjmp(ctx.jump, 1);  // NOLINT(cert-err52-cpp): libjpeg's documented error recovery; see run_guarded
}

void on_message(j_common_ptr cinfo, int msg_level) {
  if (msg_level < 0) {
    on_fatal(cinfo);
  }
}

void arena_exhausted(j_common_ptr cinfo) {
  cinfo->err->msg_code = JERR_OUT_OF_MEMORY;
  cinfo->err->msg_parm.i[0] = 0;  // NOLINT(cppcoreguidelines-pro-type-union-access): libjpeg's message parameters are a union
  on_fatal(cinfo);
}

// The arena allocator that replaces libjpeg's small/large pools.
void* arena_alloc(j_common_ptr cinfo, int pool_id, std::size_t bytes) {
  Context& ctx = context_of(cinfo);
  const std::size_t rounded = round_up(bytes, kAlign);
  if (rounded > ctx.image_bottom - ctx.permanent_top) {
    arena_exhausted(cinfo);
  }
  if (pool_id == JPOOL_PERMANENT) {
    void* p = ctx.arena + ctx.permanent_top;
    ctx.permanent_top += rounded;
    return p;
  }
  ctx.image_bottom -= rounded;
  const std::size_t used = ctx.capacity - ctx.image_bottom;
  if (used > ctx.image_high_water) {
    ctx.image_high_water = used;
  }
  return ctx.arena + ctx.image_bottom;
}

JSAMPARRAY arena_alloc_sarray(j_common_ptr cinfo, int pool_id, JDIMENSION samples_per_row, JDIMENSION rows) {
  // Rows padded as libjpeg-turbo's own manager pads them: SIMD code may touch
  // up to the next 64 samples.
  const std::size_t row_bytes = round_up(static_cast<std::size_t>(samples_per_row) * sizeof(JSAMPLE), kAlign);
  auto* pointers = static_cast<JSAMPARRAY>(arena_alloc(cinfo, pool_id, rows * sizeof(JSAMPROW)));
  auto* samples = static_cast<JSAMPLE*>(arena_alloc(cinfo, pool_id, row_bytes * rows));
  for (JDIMENSION r = 0U; r < rows; ++r) {
    pointers[r] = samples + static_cast<std::size_t>(r) * row_bytes;
  }
  return pointers;
}

JBLOCKARRAY arena_alloc_barray(j_common_ptr cinfo, int pool_id, JDIMENSION blocks_per_row, JDIMENSION rows) {
  const std::size_t row_bytes = static_cast<std::size_t>(blocks_per_row) * sizeof(JBLOCK);
  auto* pointers = static_cast<JBLOCKARRAY>(arena_alloc(cinfo, pool_id, rows * sizeof(JBLOCKROW)));
  auto* blocks = static_cast<std::uint8_t*>(arena_alloc(cinfo, pool_id, row_bytes * rows));
  for (JDIMENSION r = 0U; r < rows; ++r) {
    pointers[r] = reinterpret_cast<JBLOCKROW>(  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): raw arena bytes become libjpeg's block rows
        blocks + static_cast<std::size_t>(r) * row_bytes);
  }
  return pointers;
}

// ---- the guarded steps: plain C state only (see run_guarded) ----

void step_create(Context& ctx) { jpeg_create_decompress(&ctx.cinfo); }

void step_header(Context& ctx) {
  jpeg_mem_src(&ctx.cinfo, ctx.data, static_cast<unsigned long>(ctx.size));
  static_cast<void>(jpeg_read_header(&ctx.cinfo, TRUE));  // with require_image TRUE it returns JPEG_HEADER_OK or exits
  ctx.info.width = static_cast<int>(ctx.cinfo.image_width);
  ctx.info.height = static_cast<int>(ctx.cinfo.image_height);
  ctx.info.components = ctx.cinfo.num_components;
  ctx.info.progressive = ctx.cinfo.progressive_mode != FALSE;
}

void step_pixels(Context& ctx) {
  ctx.cinfo.out_color_space = JCS_RGB;
  ctx.cinfo.dct_method = JDCT_ISLOW;  // the same bits on every machine
  ctx.cinfo.do_fancy_upsampling = TRUE;
  static_cast<void>(jpeg_start_decompress(&ctx.cinfo));  // returns TRUE for a memory source (never suspends)
  if (ctx.cinfo.output_components != 3) {
    ctx.cinfo.err->msg_code = JERR_CONVERSION_NOTIMPL;
    on_fatal(reinterpret_cast<j_common_ptr>(&ctx.cinfo));  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): libjpeg's common-struct idiom
  }
  JSAMPROW rows[kRowBatch];
  while (ctx.cinfo.output_scanline < ctx.cinfo.output_height) {
    const int first = static_cast<int>(ctx.cinfo.output_scanline);
    int batch = static_cast<int>(ctx.cinfo.output_height) - first;
    if (batch > kRowBatch) {
      batch = kRowBatch;
    }
    for (int i = 0; i < batch; ++i) {
      rows[i] = ctx.out.row(first + i);
    }
    // jpeg_read_scanlines returns at least one row for a memory source, so
    // the loop is bounded by output_height iterations.
    if (jpeg_read_scanlines(&ctx.cinfo, rows, static_cast<JDIMENSION>(batch)) == 0U) {
      ctx.cinfo.err->msg_code = JERR_INPUT_EOF;
      on_fatal(reinterpret_cast<j_common_ptr>(&ctx.cinfo));  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast): libjpeg's common-struct idiom
    }
  }
  static_cast<void>(jpeg_finish_decompress(&ctx.cinfo));  // TRUE for a memory source
}

// The one setjmp in tcpest. libjpeg's fatal-error callback (on_fatal) longjmps
// back here. This is sound because:
//  1. `step` and the libjpeg frames it calls hold only C data (no object with a
//     destructor), so the frames that longjmp skips own nothing;
//  2. no local of this function is written between setjmp and longjmp (no
//     volatile needed), and the result goes through `ctx`, which lives outside;
//  3. after a jump the caller resets libjpeg with jpeg_abort_decompress, the
//     recovery libjpeg documents (libjpeg.txt, "Error handling").
bool run_guarded(Context& ctx, void (*step)(Context&)) noexcept {
  if (setjmp(ctx.jump) != 0) {  // NOLINT(cert-err52-cpp): see above; the only setjmp in tcpest
    return false;
  }
  step(ctx);
  return true;
}

}  // namespace

const char* to_string(CameraError error) noexcept {
  switch (error) {
    case CameraError::kNone:
      return "ok";
    case CameraError::kBadArgument:
      return "bad argument";
    case CameraError::kNotFound:
      return "not found";
    case CameraError::kIo:
      return "i/o error";
    case CameraError::kCorrupt:
      return "corrupt image data";
    case CameraError::kTruncated:
      return "truncated image data";
    case CameraError::kWrongSize:
      return "image size differs from the configured size";
    case CameraError::kUnsupported:
      return "unsupported image format";
    case CameraError::kOutOfMemory:
      return "fixed buffer too small";
    case CameraError::kEndOfStream:
      return "end of stream";
    case CameraError::kNotReady:
      return "no frame ready";
    case CameraError::kDeviceLost:
      return "device lost";
  }
  return "unknown camera error";
}

JpegDecoder::~JpegDecoder() {
  if (context_ != nullptr) {
    jpeg_destroy_decompress(&context_->cinfo);
    std::free(context_->arena);  // NOLINT(cppcoreguidelines-no-malloc): allocated with aligned_alloc in init()
    delete context_;
    context_ = nullptr;
  }
}

Status<CameraError> JpegDecoder::init(int max_width, int max_height, std::size_t arena_bytes) noexcept {
  if (context_ != nullptr || max_width <= 0 || max_height <= 0 || max_width > 16384 || max_height > 16384 ||
      arena_bytes > kMaxArenaBytes) {
    return Status<CameraError>::failure(CameraError::kBadArgument);
  }
  auto* ctx = new (std::nothrow) Context();
  if (ctx == nullptr) {
    return Status<CameraError>::failure(CameraError::kOutOfMemory);
  }
  const std::size_t row_bytes = round_up(static_cast<std::size_t>(max_width), kAlign) * 3U;
  ctx->capacity = round_up(arena_bytes != 0U ? arena_bytes : kFixedArenaBytes + kArenaRowsPerWidth * row_bytes, kAlign);
  ctx->arena = static_cast<std::uint8_t*>(std::aligned_alloc(kAlign, ctx->capacity));  // NOLINT(cppcoreguidelines-no-malloc): one aligned block at start-up, freed in the destructor
  if (ctx->arena == nullptr) {
    delete ctx;
    return Status<CameraError>::failure(CameraError::kOutOfMemory);
  }
  std::memset(ctx->arena, 0, ctx->capacity);  // pre-fault the pages now, not in the first cycle
  ctx->image_bottom = ctx->capacity;
  ctx->max_width = max_width;
  ctx->max_height = max_height;
  ctx->cinfo.err = jpeg_std_error(&ctx->jerr);
  ctx->jerr.error_exit = on_fatal;
  ctx->jerr.emit_message = on_message;
  ctx->cinfo.client_data = ctx;
  // jpeg_create_decompress reports failure through error_exit (no memory
  // for its memory manager, or a libjpeg of another version than the
  // headers'): guarded like every other libjpeg call. jpeg_destroy is safe
  // on a half-created context (it frees the memory manager if there is one).
  if (!run_guarded(*ctx, step_create)) {
    const CameraError error = ctx->error == CameraError::kOutOfMemory ? CameraError::kOutOfMemory
                                                                       : CameraError::kUnsupported;
    jpeg_destroy_decompress(&ctx->cinfo);
    std::free(ctx->arena);  // NOLINT(cppcoreguidelines-no-malloc): see above
    delete ctx;
    return Status<CameraError>::failure(error);
  }
  // From here on, libjpeg's pools come from the arena. Virtual arrays
  // (progressive decoding) keep libjpeg's own allocator: the deviation.
  ctx->cinfo.mem->alloc_small = arena_alloc;
  ctx->cinfo.mem->alloc_large = arena_alloc;
  ctx->cinfo.mem->alloc_sarray = arena_alloc_sarray;
  ctx->cinfo.mem->alloc_barray = arena_alloc_barray;
  context_ = ctx;
  return ok_status<CameraError>();
}

Result<JpegInfo, CameraError> JpegDecoder::inspect(const std::uint8_t* data, std::size_t size) noexcept {
  if (context_ == nullptr || data == nullptr || size == 0U) {
    return Result<JpegInfo, CameraError>::failure(context_ == nullptr ? CameraError::kBadArgument
                                                                      : CameraError::kTruncated);
  }
  Context& ctx = *context_;
  ctx.image_bottom = ctx.capacity;
  ctx.error = CameraError::kNone;
  ctx.message[0] = '\0';
  ctx.data = data;
  ctx.size = size;
  const bool ok = run_guarded(ctx, step_header);
  jpeg_abort_decompress(&ctx.cinfo);
  if (!ok) {
    return Result<JpegInfo, CameraError>::failure(ctx.error);
  }
  return Result<JpegInfo, CameraError>::success(ctx.info);
}

Status<CameraError> JpegDecoder::decode(const std::uint8_t* data, std::size_t size,
                                        const MutableImageView& out) noexcept {
  if (context_ == nullptr || !out.valid() || out.width > context_->max_width || out.height > context_->max_height) {
    return Status<CameraError>::failure(CameraError::kBadArgument);
  }
  if (data == nullptr || size == 0U) {
    return Status<CameraError>::failure(CameraError::kTruncated);
  }
  Context& ctx = *context_;
  ctx.image_bottom = ctx.capacity;
  ctx.error = CameraError::kNone;
  ctx.message[0] = '\0';
  ctx.data = data;
  ctx.size = size;
  ctx.out = out;
  bool ok = run_guarded(ctx, step_header);
  if (ok && (ctx.info.width != out.width || ctx.info.height != out.height)) {
    ctx.error = CameraError::kWrongSize;
    static_cast<void>(std::snprintf(ctx.message, sizeof ctx.message, "JPEG is %dx%d, expected %dx%d",
                                    ctx.info.width, ctx.info.height, out.width, out.height));  // truncation is harmless
    ok = false;
  }
  if (ok) {
    if (ctx.info.progressive) {
      ++ctx.fallback_decodes;
    }
    ok = run_guarded(ctx, step_pixels);
  }
  if (!ok) {
    jpeg_abort_decompress(&ctx.cinfo);
    return Status<CameraError>::failure(ctx.error);
  }
  return ok_status<CameraError>();
}

JpegArenaStats JpegDecoder::arena_stats() const noexcept {
  JpegArenaStats stats;
  if (context_ != nullptr) {
    stats.capacity_bytes = context_->capacity;
    stats.permanent_bytes = context_->permanent_top;
    stats.image_high_water_bytes = context_->image_high_water;
    stats.fallback_allocations = context_->fallback_decodes;
  }
  return stats;
}

const char* JpegDecoder::last_message() const noexcept { return context_ != nullptr ? context_->message : ""; }

}  // namespace hal
}  // namespace tcpest
