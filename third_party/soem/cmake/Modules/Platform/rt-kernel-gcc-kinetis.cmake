
message("rt-kernel-gcc-kinetis.cmake")

#SET_PROPERTY(GLOBAL PROPERTY ARCH kinetis)
#SET_PROPERTY(GLOBAL PROPERTY BSP twrk60)

set(MACHINE "-mfpu=vfp -mcpu=cortex-m3 -mthumb")
