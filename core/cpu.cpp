#include "cpu.h"

namespace eco {

#ifdef ECO_HAVE_AVX2_KERNELS
namespace {
bool gAvx2 = __builtin_cpu_supports("avx2");
}

bool avx2Kernels() { return gAvx2; }

bool setAvx2Kernels(bool on) {
    gAvx2 = on && __builtin_cpu_supports("avx2");
    return gAvx2;
}
#endif

}  // namespace eco
