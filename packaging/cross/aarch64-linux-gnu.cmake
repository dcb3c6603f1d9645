# Cross-compiling rcand for arm64 boards (Raspberry Pi 4/5, Jetson) with Debian's cross toolchain
# (crossbuild-essential-arm64) against the arm64 multiarch -dev packages. packaging/build-arm64.sh uses it in a build
# root that has only the arm64 libraries:
#   cmake -S . -B build -G Ninja -DCMAKE_TOOLCHAIN_FILE=packaging/cross/aarch64-linux-gnu.cmake
set(CMAKE_SYSTEM_NAME Linux)
set(CMAKE_SYSTEM_PROCESSOR aarch64)
set(CMAKE_C_COMPILER aarch64-linux-gnu-gcc)
set(CMAKE_CXX_COMPILER aarch64-linux-gnu-g++)
# Libraries and CMake packages from /usr/lib/aarch64-linux-gnu, pkg-config files from there and /usr/share.
set(CMAKE_LIBRARY_ARCHITECTURE aarch64-linux-gnu)
set(ENV{PKG_CONFIG_LIBDIR} /usr/lib/aarch64-linux-gnu/pkgconfig:/usr/share/pkgconfig)
set(ENV{PKG_CONFIG_PATH} "")
# The packages' architecture (CPack would ask dpkg, which answers for the build machine).
set(CPACK_DEBIAN_PACKAGE_ARCHITECTURE arm64)
