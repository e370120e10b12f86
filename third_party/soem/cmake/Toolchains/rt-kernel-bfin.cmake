
message("rt-kernel-kinetis.cmake")

set(CMAKE_SYSTEM_NAME rt-kernel)
set(CMAKE_SYSTEM_VERSION 1)
set(CMAKE_SYSTEM_PROCESSOR bfin)

set(ARCH bfin CACHE STRING "Architecture")
set(BSP stamp537 CACHE STRING "Board")
