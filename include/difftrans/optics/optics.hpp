// Everything of the optics layer: Fresnel, reflection/refraction, interface
// events, Beer–Lambert.
#pragma once

#include "difftrans/optics/beer_lambert.hpp"
#include "difftrans/optics/fresnel.hpp"
#include "difftrans/optics/interface.hpp"
#include "difftrans/optics/refract.hpp"
