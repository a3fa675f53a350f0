// difftrans::metrics umbrella header: Chamfer / F1, PSNR / SSIM, IoR error,
// absorption error
// (docs/metrics.md). Host code; link difftrans::io.
#pragma once

#include "difftrans/metrics/absorption.hpp"
#include "difftrans/metrics/chamfer.hpp"
#include "difftrans/metrics/image.hpp"
#include "difftrans/metrics/ior.hpp"
#include "difftrans/metrics/normals.hpp"
