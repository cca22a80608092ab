#include "tcpest/loop/prerendered_source.hpp"

#include <pthread.h>

#include <atomic>
#include <cstring>
#include <new>

#include "tcpest/loop/rendered_scene.hpp"
#include "tcpest/render/image_io.hpp"

namespace tcpest {
namespace loop {

struct PrerenderedSource::Frame {
  std::unique_ptr<std::uint8_t[]> jpeg;
  std::size_t size = 0U;
  hal::FrameTruth truth{};
  JointPrior encoder{};
};

namespace {

constexpr int kMaxThreads = 8;

struct Job {
  const solver::CameraModel* camera = nullptr;
  const solver::InstrumentModel* model = nullptr;
  const PrerenderOptions* options = nullptr;
  PrerenderedSource::Frame* frames = nullptr;
  std::atomic<std::uint32_t>* next = nullptr;
  std::atomic<std::uint32_t>* done = nullptr;
  hal::CameraError error = hal::CameraError::kNone;
};

// One rendering thread: its own renderer and encoder, frames taken from a shared counter.
void* render_worker(void* arg) noexcept {
  Job& job = *static_cast<Job*>(arg);
  const int w = job.camera->width();
  const int h = job.camera->height();
  auto scene = RenderedScene::create(*job.camera, *job.model, job.options->seed, job.options->rate_hz, 0U);
  auto encoder = render::JpegEncoder::create(w, h);
  const std::size_t stride = static_cast<std::size_t>(w) * 3U;
  std::unique_ptr<std::uint8_t[]> pixels(new (std::nothrow) std::uint8_t[stride * static_cast<std::size_t>(h)]);
  if (!scene.ok() || !encoder.ok() || !pixels) {
    job.error = hal::CameraError::kOutOfMemory;
    return nullptr;
  }
  const MutableImageView view{pixels.get(), w, h, stride};
  for (;;) {  // bounded by options->frames
    const std::uint32_t i = job.next->fetch_add(1U);
    if (i >= job.options->frames) {
      break;
    }
    PrerenderedSource::Frame& f = job.frames[i];
    const auto drawn = scene.value()->render(i, view, f.truth);
    if (!drawn.ok()) {
      job.error = drawn.error();
      break;
    }
    f.encoder = scene.value()->encoder_reading(i);
    if (!encoder.value()->encode(view.view(), job.options->jpeg_quality).ok()) {
      job.error = hal::CameraError::kOutOfMemory;
      break;
    }
    f.size = encoder.value()->size();
    f.jpeg.reset(new (std::nothrow) std::uint8_t[f.size]);
    if (!f.jpeg) {
      job.error = hal::CameraError::kOutOfMemory;
      break;
    }
    std::memcpy(f.jpeg.get(), encoder.value()->data(), f.size);
    const std::uint32_t done = job.done->fetch_add(1U) + 1U;
    if (job.options->progress != nullptr) {
      job.options->progress(done, job.options->frames);
    }
  }
  return nullptr;
}

}  // namespace

PrerenderedSource::~PrerenderedSource() = default;

Result<std::unique_ptr<PrerenderedSource>, hal::CameraError> PrerenderedSource::create(
    const solver::CameraModel& camera, const solver::InstrumentModel& model, const PrerenderOptions& options) noexcept {
  using R = Result<std::unique_ptr<PrerenderedSource>, hal::CameraError>;
  if (options.frames == 0U || options.rate_hz <= 0.0 || options.jpeg_quality < 1 || options.jpeg_quality > 100) {
    return R::failure(hal::CameraError::kBadArgument);
  }
  std::unique_ptr<PrerenderedSource> source(new (std::nothrow) PrerenderedSource());
  if (!source) {
    return R::failure(hal::CameraError::kOutOfMemory);
  }
  source->options_ = options;
  source->width_ = camera.width();
  source->height_ = camera.height();
  source->frames_.reset(new (std::nothrow) Frame[options.frames]);
  if (!source->frames_) {
    return R::failure(hal::CameraError::kOutOfMemory);
  }
  const auto init = source->decoder_.init(source->width_, source->height_);
  if (!init.ok()) {
    return R::failure(init.error());
  }
  std::atomic<std::uint32_t> next{0U};
  std::atomic<std::uint32_t> done{0U};
  int threads = options.threads < 1 ? 1 : (options.threads > kMaxThreads ? kMaxThreads : options.threads);
  Job jobs[kMaxThreads];
  pthread_t ids[kMaxThreads] = {};
  bool started[kMaxThreads] = {};
  for (int t = 0; t < threads; ++t) {
    jobs[t] = Job{&camera, &model, &source->options_, source->frames_.get(), &next, &done, hal::CameraError::kNone};
  }
  // Thread 0 is this one; the others are started here and joined below.
  for (int t = 1; t < threads; ++t) {
    started[t] = ::pthread_create(&ids[t], nullptr, render_worker, &jobs[t]) == 0;
  }
  static_cast<void>(render_worker(&jobs[0]));  // returns nullptr; errors are in the job
  for (int t = 1; t < threads; ++t) {
    if (started[t]) {
      static_cast<void>(::pthread_join(ids[t], nullptr));  // joining our own joinable thread cannot fail
    }
  }
  for (int t = 0; t < threads; ++t) {
    if (jobs[t].error != hal::CameraError::kNone) {
      return R::failure(jobs[t].error);
    }
  }
  if (done.load() != options.frames) {
    return R::failure(hal::CameraError::kOutOfMemory);
  }
  return R::success(std::move(source));
}

Status<hal::CameraError> PrerenderedSource::acquire(const MutableImageView& out, hal::FrameInfo& info) noexcept {
  if (next_ >= options_.frames) {
    if (!options_.loop) {
      return Status<hal::CameraError>::failure(hal::CameraError::kEndOfStream);
    }
    next_ = 0U;
  }
  const Frame& f = frames_[next_];
  info.timestamp_ns = hal::monotonic_now_ns();
  info.sequence = sequence_++;
  ++next_;
  const auto decoded = decoder_.decode(f.jpeg.get(), f.size, out);
  last_truth_ = decoded.ok() ? f.truth : hal::FrameTruth{};
  return decoded;
}

Status<hal::CameraError> PrerenderedSource::reopen() noexcept {
  next_ = 0U;
  return ok_status<hal::CameraError>();
}

const hal::FrameTruth& PrerenderedSource::truth(std::uint32_t index) const noexcept {
  return frames_[index < options_.frames ? index : 0U].truth;
}

JointPrior PrerenderedSource::encoder_reading(std::uint32_t index) const noexcept {
  return frames_[index < options_.frames ? index : 0U].encoder;
}

const std::uint8_t* PrerenderedSource::jpeg(std::uint32_t index, std::size_t& size) const noexcept {
  const Frame& f = frames_[index < options_.frames ? index : 0U];
  size = f.size;
  return f.jpeg.get();
}

}  // namespace loop
}  // namespace tcpest
