#include "real_fft.h"

#include <map>
#include <mutex>
#include <new>
#include <utility>
#include <vector>

#include <fftw3.h>

namespace areomap::internal {
namespace {

struct PlanPair {
  fftw_plan forward = nullptr;  // Real rows x cols -> half spectrum (keeps its input).
  fftw_plan inverse = nullptr;  // Half spectrum -> real, unnormalised (destroys its input).
};

std::size_t HalfSpectrumBytes(cv::Size size) {
  return static_cast<std::size_t>(size.height) * (size.width / 2 + 1) * sizeof(fftw_complex);
}

std::size_t RealBytes(cv::Size size) {
  return static_cast<std::size_t>(size.area()) * sizeof(double);
}

// The plans of each size, made on first use and destroyed at exit. FFTW's planner is not
// thread-safe, so planning is serialised; the plans run through fftw_execute_dft_* on other
// arrays of the same alignment (fftw_malloc's), which FFTW allows from any thread.
class PlanCache {
 public:
  PlanCache() = default;
  PlanCache(const PlanCache&) = delete;
  PlanCache& operator=(const PlanCache&) = delete;
  ~PlanCache() {
    for (auto& [size, p] : plans_) {
      if (p.forward != nullptr) fftw_destroy_plan(p.forward);
      if (p.inverse != nullptr) fftw_destroy_plan(p.inverse);
    }
  }

  const PlanPair& For(cv::Size size) {
    const std::lock_guard<std::mutex> lock(mutex_);
    PlanPair& p = plans_[{size.height, size.width}];
    if (p.forward == nullptr) {
      const FftBuffer real(RealBytes(size)), spectrum(HalfSpectrumBytes(size));
      p.forward = fftw_plan_dft_r2c_2d(size.height, size.width, real.as<double>(),
                                       spectrum.as<fftw_complex>(), FFTW_ESTIMATE);
      p.inverse = fftw_plan_dft_c2r_2d(size.height, size.width, spectrum.as<fftw_complex>(),
                                       real.as<double>(), FFTW_ESTIMATE);
      if (p.forward == nullptr || p.inverse == nullptr) throw std::bad_alloc();
    }
    return p;
  }

 private:
  std::mutex mutex_;
  std::map<std::pair<int, int>, PlanPair> plans_;
};

const PlanPair& PlansFor(cv::Size size) {
  static PlanCache cache;
  return cache.For(size);
}

// Free buffers by size, at most kMaxCachedBytes of them: a run whose templates change size from
// site to site would otherwise keep every size's buffers for good. A buffer given back beyond
// the cap first frees those of other sizes, and is itself freed if it still does not fit.
class BufferPool {
 public:
  void* Take(std::size_t bytes) {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      std::vector<void*>& free = free_[bytes];
      if (!free.empty()) {
        void* p = free.back();
        free.pop_back();
        cached_bytes_ -= bytes;
        return p;
      }
    }
    void* p = fftw_malloc(bytes);
    if (p == nullptr) throw std::bad_alloc();
    return p;
  }
  void Give(void* p, std::size_t bytes) {
    const std::lock_guard<std::mutex> lock(mutex_);
    for (auto it = free_.begin(); it != free_.end() && cached_bytes_ + bytes > kMaxCachedBytes;
         ++it) {
      if (it->first == bytes) continue;
      for (void* q : it->second) fftw_free(q);
      cached_bytes_ -= it->first * it->second.size();
      it->second.clear();
    }
    if (cached_bytes_ + bytes > kMaxCachedBytes) {
      fftw_free(p);
      return;
    }
    free_[bytes].push_back(p);
    cached_bytes_ += bytes;
  }

 private:
  static constexpr std::size_t kMaxCachedBytes = std::size_t{128} << 20;
  std::mutex mutex_;
  std::map<std::size_t, std::vector<void*>> free_;
  std::size_t cached_bytes_ = 0;
};

BufferPool& Pool() {
  static BufferPool* pool = new BufferPool;  // Never destroyed: buffers may outlive statics.
  return *pool;
}

}  // namespace

FftBuffer::FftBuffer(std::size_t bytes) : data_(Pool().Take(bytes)), bytes_(bytes) {}

FftBuffer::FftBuffer(FftBuffer&& other) noexcept
    : data_(std::exchange(other.data_, nullptr)), bytes_(std::exchange(other.bytes_, 0)) {}

FftBuffer& FftBuffer::operator=(FftBuffer&& other) noexcept {
  if (this != &other) {
    Release();
    data_ = std::exchange(other.data_, nullptr);
    bytes_ = std::exchange(other.bytes_, 0);
  }
  return *this;
}

FftBuffer::~FftBuffer() { Release(); }

void FftBuffer::Release() {
  if (data_ != nullptr) Pool().Give(data_, bytes_);
  data_ = nullptr;
  bytes_ = 0;
}

RealSpectrum RealSpectrum::Forward(const cv::Mat& src, cv::Point offset, cv::Size padded) {
  CV_Assert(src.type() == CV_64FC1 && offset.x >= 0 && offset.y >= 0 &&
            offset.x + src.cols <= padded.width && offset.y + src.rows <= padded.height);
  const PlanPair& plans = PlansFor(padded);
  const FftBuffer real(RealBytes(padded));
  cv::Mat buffer(padded, CV_64FC1, real.as<double>());
  buffer.setTo(0.0);
  src.copyTo(buffer(cv::Rect(offset, src.size())));
  RealSpectrum out;
  out.size_ = padded;
  out.data_ = FftBuffer(HalfSpectrumBytes(padded));
  fftw_execute_dft_r2c(plans.forward, real.as<double>(), out.data_.as<fftw_complex>());
  return out;
}

cv::Mat Correlate(const RealSpectrum& a, const RealSpectrum& b, int rows) {
  CV_Assert(a.size_ == b.size_ && rows >= 0 && rows <= a.size_.height);
  const cv::Size size = a.size_;
  const std::size_t n = static_cast<std::size_t>(size.height) * (size.width / 2 + 1);
  const FftBuffer product(HalfSpectrumBytes(size));
  const fftw_complex* pa = a.data_.as<fftw_complex>();
  const fftw_complex* pb = b.data_.as<fftw_complex>();
  fftw_complex* pp = product.as<fftw_complex>();
  for (std::size_t k = 0; k < n; ++k) {  // A conj(B).
    pp[k][0] = pa[k][0] * pb[k][0] + pa[k][1] * pb[k][1];
    pp[k][1] = pa[k][1] * pb[k][0] - pa[k][0] * pb[k][1];
  }
  const FftBuffer real(RealBytes(size));
  fftw_execute_dft_c2r(PlansFor(size).inverse, pp, real.as<double>());
  cv::Mat out;
  cv::Mat(size, CV_64FC1, real.as<double>())
      .rowRange(0, rows)
      .convertTo(out, CV_64F, 1.0 / static_cast<double>(size.area()));
  return out;
}

}  // namespace areomap::internal
