// Mathematical constants as constexpr variable templates, one per scalar type.
#pragma once

namespace difftrans {

template <class T> inline constexpr T pi_v = T(3.141592653589793238462643383279502884L);
template <class T> inline constexpr T two_pi_v = T(6.283185307179586476925286766559005768L);
template <class T> inline constexpr T inv_pi_v = T(0.318309886183790671537767526745028724L);
template <class T> inline constexpr T inv_two_pi_v = T(0.159154943091895335768883763372514362L);

}  // namespace difftrans
