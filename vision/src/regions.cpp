// Stage 1 (regions.hpp): per-pixel classification through the lookup table,
// then connected components (8-connected) over runs of equal class, with
// union-find on the runs and moments accumulated per run in closed form.
#include <cstring>
#include <new>

#include "tcpest/vision/regions.hpp"

namespace tcpest {
namespace vision {
namespace {

#if defined(__BYTE_ORDER__) && defined(__ORDER_LITTLE_ENDIAN__) && __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
constexpr bool kLittleEndian = true;
#else
constexpr bool kLittleEndian = false;
#endif

// Run indices are int32 (they are also union-find parents); never negative.
std::size_t idx(std::int32_t i) noexcept { return static_cast<std::size_t>(i); }

}  // namespace

bool ClassifierLut::build(const ColorModel& model) noexcept {
  model_ = model;
  table_.reset(new (std::nothrow) std::uint8_t[kEntries]);
  constexpr int kLevels = 1 << kBitsPerChannel;
  constexpr int kCell = 1 << kShift;
  // Class at both ends of every cell, per channel: values q*kCell and
  // q*kCell + kCell - 1 (start-up scratch, 2 MiB).
  constexpr int kEnds = 2 * kLevels;
  std::unique_ptr<std::uint8_t[]> ends(new (std::nothrow) std::uint8_t[static_cast<std::size_t>(kEnds * kEnds * kEnds)]);
  if (table_ == nullptr || ends == nullptr) {
    table_.reset();
    return false;
  }
  const auto value = [](int e) noexcept { return static_cast<std::uint8_t>((e / 2) * kCell + (e % 2) * (kCell - 1)); };
  const auto at = [](int r, int g, int b) noexcept {
    return (static_cast<std::size_t>(r) * kEnds + static_cast<std::size_t>(g)) * kEnds + static_cast<std::size_t>(b);
  };
  for (int r = 0; r < kEnds; ++r) {
    for (int g = 0; g < kEnds; ++g) {
      for (int b = 0; b < kEnds; ++b) {
        ends[at(r, g, b)] = static_cast<std::uint8_t>(model.classify(value(r), value(g), value(b)));
      }
    }
  }
  block_count_ = 0U;
  for (int r = 0; r < kLevels; ++r) {
    for (int g = 0; g < kLevels; ++g) {
      for (int b = 0; b < kLevels; ++b) {
        const std::uint8_t first = ends[at(2 * r, 2 * g, 2 * b)];
        std::uint8_t cls = first;
        for (int corner = 1; corner < 8; ++corner) {
          if (ends[at(2 * r + (corner & 1), 2 * g + ((corner >> 1) & 1), 2 * b + ((corner >> 2) & 1))] != first) {
            cls = kAmbiguous;
            break;
          }
        }
        if (cls == kAmbiguous) {
          ++block_count_;
        }
        table_[(static_cast<std::size_t>(r) << (2 * kBitsPerChannel)) | (static_cast<std::size_t>(g) << kBitsPerChannel) |
               static_cast<std::size_t>(b)] = cls;
      }
    }
  }
  // Second level: the exact class of every colour of the ambiguous cells.
  block_of_cell_.reset(new (std::nothrow) std::uint32_t[kEntries]);
  blocks_.reset(new (std::nothrow) std::uint8_t[static_cast<std::size_t>(block_count_) * kBlockSize + 1U]);
  if (block_of_cell_ == nullptr || blocks_ == nullptr) {
    table_.reset();
    return false;
  }
  std::uint32_t next = 0U;
  for (std::uint32_t cell = 0U; cell < kEntries; ++cell) {
    block_of_cell_[cell] = 0U;
    if (table_[cell] != kAmbiguous) {
      continue;
    }
    block_of_cell_[cell] = next;
    const std::uint32_t r0 = (cell >> (2 * kBitsPerChannel)) << kShift;
    const std::uint32_t g0 = ((cell >> kBitsPerChannel) & (kLevels - 1U)) << kShift;
    const std::uint32_t b0 = (cell & (kLevels - 1U)) << kShift;
    for (std::uint32_t o = 0U; o < kBlockSize; ++o) {
      const auto red = static_cast<std::uint8_t>(r0 + (o >> (2 * kShift)));
      const auto green = static_cast<std::uint8_t>(g0 + ((o >> kShift) & ((1U << kShift) - 1U)));
      const auto blue = static_cast<std::uint8_t>(b0 + (o & ((1U << kShift) - 1U)));
      blocks_[static_cast<std::size_t>(next) * kBlockSize + o] = static_cast<std::uint8_t>(model.classify(red, green, blue));
    }
    ++next;
  }
  return true;
}

Result<std::unique_ptr<RegionFinder>, VisionError> RegionFinder::create(const RegionsConfig& config,
                                                                        const ColorModel& colors) noexcept {
  using R = Result<std::unique_ptr<RegionFinder>, VisionError>;
  if (config.max_width <= 0 || config.max_height <= 0 || config.max_width > 8192 || config.max_height > 8192 ||
      !colors.valid() || config.min_region_area < 1 || config.classify_step < 0 || config.classify_step > 2) {
    return R::failure(VisionError::BadParameter);
  }
  std::unique_ptr<RegionFinder> f(new (std::nothrow) RegionFinder());
  if (f == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  f->config_ = config;
  if (!f->lut_.build(colors)) {
    return R::failure(VisionError::OutOfMemory);  // the table's allocations are its only failure
  }
  const std::size_t pixels = static_cast<std::size_t>(config.max_width) * static_cast<std::size_t>(config.max_height);
  // A run needs at least one classified pixel and one separating pixel.
  f->max_runs_ = static_cast<std::int32_t>(pixels / 2U + 1U);
  f->classes_.reset(new (std::nothrow) std::uint8_t[pixels]);
  f->runs_.reset(new (std::nothrow) Run[static_cast<std::size_t>(f->max_runs_)]);
  f->region_of_root_.reset(new (std::nothrow) std::int32_t[static_cast<std::size_t>(f->max_runs_)]);
  f->candidates_.reset(new (std::nothrow) Region[kMaxCandidates]);
  const auto grid_row_bytes = static_cast<std::size_t>(config.max_width);
  f->grid_row_.reset(new (std::nothrow) std::uint8_t[grid_row_bytes]);
  if (f->classes_ == nullptr || f->runs_ == nullptr || f->region_of_root_ == nullptr || f->candidates_ == nullptr ||
      f->grid_row_ == nullptr) {
    return R::failure(VisionError::OutOfMemory);
  }
  return R::success(std::move(f));
}

std::int32_t RegionFinder::find_root(std::int32_t run) noexcept {
  // Path halving; terminates because parents always point to lower indices.
  std::int32_t i = run;
  while (runs_[idx(i)].parent != i) {
    runs_[idx(i)].parent = runs_[idx(runs_[idx(i)].parent)].parent;
    i = runs_[idx(i)].parent;
  }
  return i;
}

int classify_step_for(int configured_step, int width, int height) noexcept {
  if (configured_step == 1 || configured_step == 2) {
    return configured_step;
  }
  const std::int64_t pixels = static_cast<std::int64_t>(width) * static_cast<std::int64_t>(height);
  return pixels >= kAutoStepMinPixels ? 2 : 1;
}

namespace {

// First index in [x, count) whose class differs from `cls`, or count. Spans
// of one class (background most of all) are skipped eight at a time.
int span_end(const std::uint8_t* classes, int x, int count, std::uint8_t cls) noexcept {
  const std::uint64_t pattern = std::uint64_t{cls} * 0x0101010101010101ULL;
  while (x + 8 <= count) {
    std::uint64_t word = 0U;
    std::memcpy(&word, classes + x, sizeof word);
    if (word != pattern) {
      break;
    }
    x += 8;
  }
  while (x < count && classes[x] == cls) {
    ++x;
  }
  return x;
}

}  // namespace

void RegionFinder::classify_row(const std::uint8_t* px, int count, int step, std::uint8_t* out) const noexcept {
  // One table read per pixel; the second level only in ambiguous cells (a
  // few per cent of the colours, rare in a frame).
  const std::uint8_t* table = lut_.table();
  const std::size_t stride = 3U * static_cast<std::size_t>(step);
  // All pixels but the last are read as one 4-byte word (the pixel and the
  // next byte of the row): fewer instructions per pixel than three byte
  // loads (measured, docs/vision.md). Byte loads on a big-endian target.
  const int wide = kLittleEndian ? count - 1 : 0;
  for (int x = 0; x < wide; ++x) {
    std::uint32_t v = 0U;
    std::memcpy(&v, px, sizeof v);
    // index(): red, green, blue from the high bits of the cell down.
    constexpr std::uint32_t kBits = ClassifierLut::kBitsPerChannel;
    constexpr std::uint32_t kShift = ClassifierLut::kShift;
    constexpr std::uint32_t kMask = (1U << kBits) - 1U;
    const std::uint32_t cell = (((v >> kShift) & kMask) << (2U * kBits)) | (((v >> (8U + kShift)) & kMask) << kBits) |
                               ((v >> (16U + kShift)) & kMask);
    std::uint8_t c = table[cell];
    if (c == ClassifierLut::kAmbiguous) {
      c = lut_.fine(cell, px[0], px[1], px[2]);
    }
    out[x] = c;
    px += stride;
  }
  for (int x = wide > 0 ? wide : 0; x < count; ++x) {
    const std::uint32_t cell = ClassifierLut::index(px[0], px[1], px[2]);
    std::uint8_t c = table[cell];
    if (c == ClassifierLut::kAmbiguous) {
      c = lut_.fine(cell, px[0], px[1], px[2]);
    }
    out[x] = c;
    px += stride;
  }
}

bool RegionFinder::cut_runs(const std::uint8_t* classes, int count, int grid_y, std::int32_t& run_count) noexcept {
  int x = 0;
  // Every iteration consumes at least one class: at most `count` iterations.
  while (x < count) {
    x = span_end(classes, x, count, 0U);
    if (x >= count) {
      break;
    }
    const std::uint8_t cls = classes[x];
    const int start = x;
    x = span_end(classes, x + 1, count, cls);
    if (run_count >= max_runs_) {
      return false;
    }
    Run& r = runs_[idx(run_count)];
    r.parent = run_count;
    r.y = static_cast<std::int16_t>(grid_y);
    r.x0 = static_cast<std::int16_t>(start);
    r.x1 = static_cast<std::int16_t>(x);
    r.cls = cls;
    ++run_count;
  }
  return true;
}

Status<VisionError> RegionFinder::find(const ImageView& image, RegionSet& out) noexcept {
  out.regions.clear();
  out.too_many_regions = false;
  out.run_count = 0;
  if (!image.valid()) {
    return Status<VisionError>::failure(VisionError::BadImage);
  }
  if (image.width > config_.max_width || image.height > config_.max_height) {
    return Status<VisionError>::failure(VisionError::ImageTooLarge);
  }
  width_ = image.width;
  height_ = image.height;
  image_ = image;
  const int step = classify_step_for(config_.classify_step, width_, height_);
  step_ = step;
  std::int32_t run_count = 0;
  if (!classify_and_label(image, step, run_count)) {
    out.too_many_regions = true;
    return Status<VisionError>::failure(VisionError::TooManyRuns);
  }
  out.run_count = run_count;
  bool overflow = false;
  const std::size_t candidate_count = accumulate_candidates(run_count, step, overflow);
  const std::size_t kept = finish_candidates(candidate_count, step);
  if (overflow) {
    out.too_many_regions = true;
  }
  select_regions(kept, out);
  return ok_status<VisionError>();
}

bool RegionFinder::classify_and_label(const ImageView& image, int step, std::int32_t& run_count) noexcept {
  // The grid: pixels (step * gx, step * gy), which stand for the step x step
  // block starting there.
  const int grid_width = (width_ + step - 1) / step;
  const int grid_height = (height_ + step - 1) / step;
  const auto row_bytes = static_cast<std::size_t>(width_);
  std::int32_t prev_begin = 0;
  std::int32_t prev_end = 0;
  for (int gy = 0; gy < grid_height; ++gy) {
    const int y = gy * step;
    std::uint8_t* cls_row = classes_.get() + static_cast<std::size_t>(y) * row_bytes;
    const std::int32_t row_begin = run_count;
    const std::uint8_t* grid_classes = cls_row;
    if (step == 1) {
      classify_row(image.row(y), width_, 1, cls_row);
    } else {
      // Grid classes first, then the full-size class image (stage 3 reads
      // it): each class fills its block of the row and the rows below.
      std::uint8_t* grid = grid_row_.get();
      classify_row(image.row(y), grid_width, 2, grid);
      grid_classes = grid;
      const int pairs = width_ / 2;
      for (int gx = 0; gx < pairs; ++gx) {
        const auto pair = static_cast<std::uint16_t>(grid[gx] * 0x0101U);
        std::memcpy(cls_row + 2 * static_cast<std::size_t>(gx), &pair, sizeof pair);
      }
      if ((width_ & 1) != 0) {
        cls_row[width_ - 1] = grid[grid_width - 1];
      }
      if (y + 1 < height_) {
        std::memcpy(cls_row + row_bytes, cls_row, row_bytes);
      }
    }
    if (!cut_runs(grid_classes, grid_width, gy, run_count)) {
      return false;
    }
    join_with_previous_row(row_begin, run_count, prev_begin, prev_end);
    prev_begin = row_begin;
    prev_end = run_count;
  }
  return true;
}

void RegionFinder::join_with_previous_row(std::int32_t row_begin, std::int32_t row_end, std::int32_t prev_begin,
                                              std::int32_t prev_end) noexcept {
  // 8-connectivity with the previous row: runs overlap when
  // [x0 - 1, x1] and [p.x0, p.x1) intersect.
  std::int32_t p = prev_begin;
  for (std::int32_t i = row_begin; i < row_end; ++i) {
    const Run& cur = runs_[idx(i)];
    while (p < prev_end && runs_[idx(p)].x1 < cur.x0) {
      ++p;
    }
    for (std::int32_t q = p; q < prev_end && runs_[idx(q)].x0 <= cur.x1; ++q) {
      if (runs_[idx(q)].cls != cur.cls) {
        continue;
      }
      const std::int32_t a = find_root(i);
      const std::int32_t b = find_root(q);
      if (a != b) {
        // The lower index becomes the root: parents point backwards.
        if (a < b) {
          runs_[idx(b)].parent = a;
        } else {
          runs_[idx(a)].parent = b;
        }
      }
    }
  }
}

std::size_t RegionFinder::accumulate_candidates(std::int32_t run_count, int step, bool& overflow) noexcept {
  // Moments per component, accumulated per run in closed form.
  // Areas per component first (indexed by root), so that only components of
  // at least the minimum area take one of the kMaxCandidates slots.
  for (std::int32_t i = 0; i < run_count; ++i) {
    region_of_root_[idx(i)] = 0;
  }
  for (std::int32_t i = 0; i < run_count; ++i) {
    region_of_root_[idx(find_root(i))] += runs_[idx(i)].x1 - runs_[idx(i)].x0;
  }
  // Areas in pixels: a grid point stands for step x step pixels.
  const std::int32_t cell_area = step * step;
  std::size_t candidate_count = 0U;
  overflow = false;
  for (std::int32_t i = 0; i < run_count; ++i) {
    const std::int32_t root = find_root(i);
    std::int32_t slot = -1;
    if (root == i) {
      const std::int32_t area = region_of_root_[idx(i)] * cell_area;
      if (area >= config_.min_region_area) {
        if (candidate_count < kMaxCandidates) {
          slot = static_cast<std::int32_t>(candidate_count);
          Region& reg = candidates_[candidate_count];
          reg = Region{};
          reg.cls = static_cast<PixelClass>(runs_[idx(i)].cls);
          reg.x_min = runs_[idx(i)].x0;
          reg.x_max = runs_[idx(i)].x1 - 1;
          reg.y_min = runs_[idx(i)].y;
          reg.y_max = runs_[idx(i)].y;
          ++candidate_count;
        } else {
          overflow = true;
        }
      }
      region_of_root_[idx(i)] = slot;
    } else {
      slot = region_of_root_[idx(root)];
    }
    if (slot >= 0) {
      add_run_moments(runs_[idx(i)], candidates_[static_cast<std::size_t>(slot)]);
    }
  }
  return candidate_count;
}

void RegionFinder::add_run_moments(const Run& r, Region& reg) noexcept {
  const double n = static_cast<double>(r.x1 - r.x0);
  const double a = static_cast<double>(r.x0);
  const double b = static_cast<double>(r.x1 - 1);
  const double y = static_cast<double>(r.y);
  const double sx = n * (a + b) * 0.5;
  // sum of x^2 over a..b
  const double sxx = (b * (b + 1.0) * (2.0 * b + 1.0) - (a - 1.0) * a * (2.0 * a - 1.0)) / 6.0;
  // Raw sums are kept in the covariance fields until the end (finish_candidates).
  reg.area += r.x1 - r.x0;
  reg.centroid.x += sx;
  reg.centroid.y += n * y;
  reg.cov_xx += sxx;
  reg.cov_xy += sx * y;
  reg.cov_yy += n * y * y;
  if (r.x0 < reg.x_min) {
    reg.x_min = r.x0;
  }
  if (r.x1 - 1 > reg.x_max) {
    reg.x_max = r.x1 - 1;
  }
  reg.y_max = r.y;  // rows are visited in order
}

std::size_t RegionFinder::finish_candidates(std::size_t candidate_count, int step) noexcept {
  // Raw sums to centroid and central moments (grid units), then pixels: a
  // grid point (gx, gy) is pixel (step gx, step gy) and stands for a step x
  // step cell, whose footprint variance step^2 / 12 the scaled 1/12 gives.
  std::size_t kept = 0U;
  const auto scale = static_cast<double>(step);
  const std::int32_t cell_area = step * step;
  const std::int32_t last_x = width_ - 1;
  const std::int32_t last_y = height_ - 1;
  for (std::size_t i = 0U; i < candidate_count; ++i) {
    Region reg = candidates_[i];
    const double n = static_cast<double>(reg.area);
    const double mx = reg.centroid.x / n;
    const double my = reg.centroid.y / n;
    reg.cov_xx = scale * scale * (reg.cov_xx / n - mx * mx + 1.0 / 12.0);  // + the cell's footprint
    reg.cov_xy = scale * scale * (reg.cov_xy / n - mx * my);
    reg.cov_yy = scale * scale * (reg.cov_yy / n - my * my + 1.0 / 12.0);
    reg.centroid = Point{scale * mx, scale * my};
    reg.area *= cell_area;
    if (reg.area < config_.min_region_area) {
      continue;
    }
    // The bounding box of the region's cells in the class image.
    reg.x_min *= step;
    reg.y_min *= step;
    reg.x_max = reg.x_max * step + step - 1 < last_x ? reg.x_max * step + step - 1 : last_x;
    reg.y_max = reg.y_max * step + step - 1 < last_y ? reg.y_max * step + step - 1 : last_y;
    reg.update_shape();
    candidates_[kept] = reg;
    ++kept;
  }
  return kept;
}

void RegionFinder::select_regions(std::size_t candidate_count, RegionSet& out) noexcept {
  if (candidate_count > kMaxRegions) {
    out.too_many_regions = true;
    // Partial selection sort: the kMaxRegions largest first.
    for (std::size_t i = 0U; i < kMaxRegions; ++i) {
      std::size_t best = i;
      for (std::size_t j = i + 1U; j < candidate_count; ++j) {
        if (candidates_[j].area > candidates_[best].area) {
          best = j;
        }
      }
      if (best != i) {
        const Region tmp = candidates_[i];
        candidates_[i] = candidates_[best];
        candidates_[best] = tmp;
      }
    }
    candidate_count = kMaxRegions;
  }
  for (std::size_t i = 0U; i < candidate_count; ++i) {
    static_cast<void>(out.regions.push_back(candidates_[i]));  // cannot fail: at most kMaxRegions
  }
}

}  // namespace vision
}  // namespace tcpest
