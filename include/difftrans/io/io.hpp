// difftrans::io umbrella header: meshes (OBJ, PLY), images (PNG, HDR, EXR),
// JSON, scene directories and COLMAP models. Host code; link difftrans::io.
#pragma once

#include "difftrans/io/colmap.hpp"
#include "difftrans/io/dataset.hpp"
#include "difftrans/io/error.hpp"
#include "difftrans/io/frames.hpp"
#include "difftrans/io/image.hpp"
#include "difftrans/io/image_file.hpp"
#include "difftrans/io/json.hpp"
#include "difftrans/io/mesh.hpp"
#include "difftrans/io/mesh_file.hpp"
