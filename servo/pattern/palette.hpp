// Colours the projector shows for each pattern symbol. The paper's pattern uses three:
// 0 blue, 1 green, 2 red (the projector's primaries, the easiest to tell apart by hue).
#pragma once

#include <array>
#include <cstdint>
#include <stdexcept>
#include <string>

namespace pattern {

struct Rgb {
  std::uint8_t r, g, b;
};

// Symbols beyond the three primaries use secondaries, then mixed hues (up to k = 10).
inline constexpr std::array<Rgb, 10> kPalette{{{0, 0, 255},
                                               {0, 255, 0},
                                               {255, 0, 0},
                                               {255, 255, 0},
                                               {0, 255, 255},
                                               {255, 0, 255},
                                               {255, 128, 0},
                                               {128, 0, 255},
                                               {0, 255, 128},
                                               {255, 255, 255}}};

inline Rgb symbol_colour(int symbol) {
  if (symbol < 0 || symbol >= static_cast<int>(kPalette.size()))
    throw std::out_of_range("pattern symbol " + std::to_string(symbol) + " has no colour (0..9)");
  return kPalette[static_cast<std::size_t>(symbol)];
}

}  // namespace pattern
