#include "real_fft.h"

#include <map>
#include <mutex>
#include <new>
#include <utility>
#include <vector>

#include <fftw3.h>

namespace areomap::internal {
namespace {

// FFTW's double (fftw_) and single (fftwf_) precision interfaces.
template <class Real>
struct Fftw;

template <>
struct Fftw<double> {
  using Plan = fftw_plan;
  using Complex = fftw_complex;
  static Plan R2c(cv::Size s, double* in, Complex* out) {
    return fftw_plan_dft_r2c_2d(s.height, s.width, in, out, FFTW_ESTIMATE);
  }
  static Plan C2r(cv::Size s, Complex* in, double* out) {
    return fftw_plan_dft_c2r_2d(s.height, s.width, in, out, FFTW_ESTIMATE);
  }
  static void ExecuteR2c(Plan p, double* in, Complex* out) { fftw_execute_dft_r2c(p, in, out); }
  static void ExecuteC2r(Plan p, Complex* in, double* out) { fftw_execute_dft_c2r(p, in, out); }
  static void Destroy(Plan p) { fftw_destroy_plan(p); }
  static constexpr int kCvType = CV_64FC1;
};

template <>
struct Fftw<float> {
  using Plan = fftwf_plan;
  using Complex = fftwf_complex;
  static Plan R2c(cv::Size s, float* in, Complex* out) {
    return fftwf_plan_dft_r2c_2d(s.height, s.width, in, out, FFTW_ESTIMATE);
  }
  static Plan C2r(cv::Size s, Complex* in, float* out) {
    return fftwf_plan_dft_c2r_2d(s.height, s.width, in, out, FFTW_ESTIMATE);
  }
  static void ExecuteR2c(Plan p, float* in, Complex* out) { fftwf_execute_dft_r2c(p, in, out); }
  static void ExecuteC2r(Plan p, Complex* in, float* out) { fftwf_execute_dft_c2r(p, in, out); }
  static void Destroy(Plan p) { fftwf_destroy_plan(p); }
  static constexpr int kCvType = CV_32FC1;
};

template <class Real>
struct PlanPair {
  typename Fftw<Real>::Plan forward = nullptr;  // Real rows x cols -> half spectrum (keeps input).
  typename Fftw<Real>::Plan inverse = nullptr;  // Half spectrum -> real, unnormalised.
};

template <class Real>
std::size_t HalfSpectrumBytes(cv::Size size) {
  return static_cast<std::size_t>(size.height) * (size.width / 2 + 1) *
         sizeof(typename Fftw<Real>::Complex);
}

template <class Real>
std::size_t RealBytes(cv::Size size) {
  return static_cast<std::size_t>(size.area()) * sizeof(Real);
}

// The plans of each size, made on first use and destroyed at exit. FFTW's planner is not
// thread-safe, so planning is serialised (each precision is a library of its own, with its own
// planner); the plans run through the new-array execute functions on other arrays of the same
// alignment (fftw_malloc's), which FFTW allows from any thread.
template <class Real>
class PlanCache {
 public:
  PlanCache() = default;
  PlanCache(const PlanCache&) = delete;
  PlanCache& operator=(const PlanCache&) = delete;
  ~PlanCache() {
    for (auto& [size, p] : plans_) {
      if (p.forward != nullptr) Fftw<Real>::Destroy(p.forward);
      if (p.inverse != nullptr) Fftw<Real>::Destroy(p.inverse);
    }
  }

  const PlanPair<Real>& For(cv::Size size) {
    const std::lock_guard<std::mutex> lock(mutex_);
    PlanPair<Real>& p = plans_[{size.height, size.width}];
    if (p.forward == nullptr) {
      using Complex = typename Fftw<Real>::Complex;
      const FftBuffer real(RealBytes<Real>(size)), spectrum(HalfSpectrumBytes<Real>(size));
      p.forward = Fftw<Real>::R2c(size, real.as<Real>(), spectrum.as<Complex>());
      p.inverse = Fftw<Real>::C2r(size, spectrum.as<Complex>(), real.as<Real>());
      if (p.forward == nullptr || p.inverse == nullptr) throw std::bad_alloc();
    }
    return p;
  }

 private:
  std::mutex mutex_;
  std::map<std::pair<int, int>, PlanPair<Real>> plans_;
};

template <class Real>
const PlanPair<Real>& PlansFor(cv::Size size) {
  static PlanCache<Real> cache;
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

template <class Real>
RealSpectrum<Real> RealSpectrum<Real>::Forward(const cv::Mat& src, cv::Point offset,
                                               cv::Size padded) {
  CV_Assert(src.type() == CV_64FC1 && offset.x >= 0 && offset.y >= 0 &&
            offset.x + src.cols <= padded.width && offset.y + src.rows <= padded.height);
  const PlanPair<Real>& plans = PlansFor<Real>(padded);
  const FftBuffer real(RealBytes<Real>(padded));
  cv::Mat buffer(padded, Fftw<Real>::kCvType, real.as<Real>());
  buffer.setTo(0.0);
  cv::Mat placed = buffer(cv::Rect(offset, src.size()));
  src.convertTo(placed, Fftw<Real>::kCvType);
  RealSpectrum out;
  out.size_ = padded;
  out.data_ = FftBuffer(HalfSpectrumBytes<Real>(padded));
  Fftw<Real>::ExecuteR2c(plans.forward, real.as<Real>(),
                         out.data_.template as<typename Fftw<Real>::Complex>());
  return out;
}

template <class Real>
cv::Mat Correlate(const RealSpectrum<Real>& a, const RealSpectrum<Real>& b, int rows) {
  using Complex = typename Fftw<Real>::Complex;
  CV_Assert(a.size_ == b.size_ && rows >= 0 && rows <= a.size_.height);
  const cv::Size size = a.size_;
  const std::size_t n = static_cast<std::size_t>(size.height) * (size.width / 2 + 1);
  const FftBuffer product(HalfSpectrumBytes<Real>(size));
  const Complex* pa = a.data_.template as<Complex>();
  const Complex* pb = b.data_.template as<Complex>();
  Complex* pp = product.as<Complex>();
  for (std::size_t k = 0; k < n; ++k) {  // A conj(B).
    pp[k][0] = pa[k][0] * pb[k][0] + pa[k][1] * pb[k][1];
    pp[k][1] = pa[k][1] * pb[k][0] - pa[k][0] * pb[k][1];
  }
  const FftBuffer real(RealBytes<Real>(size));
  Fftw<Real>::ExecuteC2r(PlansFor<Real>(size).inverse, pp, real.as<Real>());
  cv::Mat out;
  cv::Mat(size, Fftw<Real>::kCvType, real.as<Real>())
      .rowRange(0, rows)
      .convertTo(out, CV_64F, 1.0 / static_cast<double>(size.area()));
  return out;
}

template class RealSpectrum<double>;
template class RealSpectrum<float>;
template cv::Mat Correlate(const RealSpectrum<double>&, const RealSpectrum<double>&, int);
template cv::Mat Correlate(const RealSpectrum<float>&, const RealSpectrum<float>&, int);

}  // namespace areomap::internal
