// Real 2-D discrete Fourier transforms for the masked NCC's FFT route (masked_ncc.cc), through
// FFTW in double or single precision (Real = double or float). Internal header.
//
// Plans are made with FFTW_ESTIMATE: the algorithm depends on the size alone, so the same inputs
// give the same bits on every run (FFTW_MEASURE picks by timing, which varies). Plans are cached
// per size and precision for the life of the process; the planner runs under a lock, transforms
// run concurrently from any thread. Work buffers are kept in a process-wide pool (at most 128 MB
// of free ones) and reused: fresh buffers of this size cost more in page faults than the
// transforms themselves. Allocation failure throws std::bad_alloc.
#pragma once

#include <cstddef>

#include <opencv2/core.hpp>

namespace areomap::internal {

// A buffer of at least `bytes` bytes, aligned for FFTW, taken from the pool and given back to it
// on destruction. Not copyable.
class FftBuffer {
 public:
  FftBuffer() = default;
  explicit FftBuffer(std::size_t bytes);
  FftBuffer(FftBuffer&& other) noexcept;
  FftBuffer& operator=(FftBuffer&& other) noexcept;
  FftBuffer(const FftBuffer&) = delete;
  FftBuffer& operator=(const FftBuffer&) = delete;
  ~FftBuffer();

  template <class T>
  T* as() const {
    return static_cast<T*>(data_);
  }

 private:
  void Release();
  void* data_ = nullptr;
  std::size_t bytes_ = 0;
};

template <class Real>
class RealSpectrum;

// corr(a, b)(s) = sum_x a(x + s) b(x), circular over the spectra's size (both the same): the
// inverse transform of A conj(B), scaled. Returns its first `rows` rows (CV_64FC1, all columns).
template <class Real>
cv::Mat Correlate(const RealSpectrum<Real>& a, const RealSpectrum<Real>& b, int rows);

// The half spectrum (rows x (cols / 2 + 1) complex values, FFTW's r2c layout) of a real image of
// `size()`, in precision Real.
template <class Real>
class RealSpectrum {
 public:
  // The spectrum of `src` (CV_64FC1, rounded to Real) placed at `offset` in a zero image of
  // `padded` size; the source must fit.
  static RealSpectrum Forward(const cv::Mat& src, cv::Point offset, cv::Size padded);

  cv::Size size() const { return size_; }

 private:
  friend cv::Mat Correlate<Real>(const RealSpectrum& a, const RealSpectrum& b, int rows);
  cv::Size size_;
  FftBuffer data_;
};

extern template class RealSpectrum<double>;
extern template class RealSpectrum<float>;
extern template cv::Mat Correlate(const RealSpectrum<double>&, const RealSpectrum<double>&, int);
extern template cv::Mat Correlate(const RealSpectrum<float>&, const RealSpectrum<float>&, int);

}  // namespace areomap::internal
