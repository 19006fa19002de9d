# Finds every third-party package as an imported target. All are Debian 12 packages,
# installed by scripts/install-deps.sh.

# GeographicLib ships its find module here on Debian.
list(APPEND CMAKE_MODULE_PATH /usr/share/cmake/geographiclib)

find_package(Eigen3 3.4 REQUIRED NO_MODULE)           # Eigen3::Eigen
find_package(OpenCV 4 REQUIRED COMPONENTS core imgproc imgcodecs calib3d features2d ximgproc dnn)
find_package(Ceres 2 REQUIRED)                         # Ceres::ceres
find_package(CGAL 5 REQUIRED)                          # CGAL::CGAL
find_package(GeographicLib 2 REQUIRED)                 # GeographicLib::GeographicLib
find_package(OpenImageIO REQUIRED)                     # OpenImageIO::OpenImageIO
find_package(GDAL 3 REQUIRED)                          # GDAL::GDAL
find_package(TBB REQUIRED)                             # TBB::tbb
find_package(CLI11 2 REQUIRED)                         # CLI11::CLI11
find_package(nlohmann_json 3 REQUIRED)                 # nlohmann_json::nlohmann_json
find_package(GTest REQUIRED)                           # GTest::gtest, GTest::gtest_main
find_package(benchmark REQUIRED)                       # benchmark::benchmark
find_package(PROJ REQUIRED CONFIG)                     # PROJ::proj
find_package(PkgConfig REQUIRED)
# FFTW (GPL-2+, like CGAL's triangulations that libmap links): the masked NCC's transforms.
# Double precision, and single precision for the decision's chance-level surfaces (both in
# libfftw3-dev).
pkg_check_modules(FFTW3 REQUIRED IMPORTED_TARGET GLOBAL fftw3)    # PkgConfig::FFTW3
pkg_check_modules(FFTW3F REQUIRED IMPORTED_TARGET GLOBAL fftw3f)  # PkgConfig::FFTW3F

# OpenCV's config exports plain target names; give them one namespaced target.
if(NOT TARGET areomap_opencv)
  add_library(areomap_opencv INTERFACE)
  target_link_libraries(areomap_opencv INTERFACE ${OpenCV_LIBS})
  target_include_directories(areomap_opencv SYSTEM INTERFACE ${OpenCV_INCLUDE_DIRS})
  add_library(OpenCV::OpenCV ALIAS areomap_opencv)
endif()

# GeographicLib's Debian find module may define only variables.
if(NOT TARGET GeographicLib::GeographicLib)
  add_library(GeographicLib::GeographicLib INTERFACE IMPORTED)
  target_link_libraries(GeographicLib::GeographicLib INTERFACE ${GeographicLib_LIBRARIES})
  target_include_directories(GeographicLib::GeographicLib SYSTEM INTERFACE ${GeographicLib_INCLUDE_DIRS})
endif()
