// A mesh's diffuse texture: the image its material names (an OBJ's `map_Kd`), read from a PNG
// beside the mesh. It multiplies the surface's albedo per channel where the mesh's texture
// coordinates put it; the geometry, and so the truth, does not depend on it.
#pragma once

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace sim {

// Limits for one texture image (docs/topics.md, Safety).
inline constexpr std::uintmax_t kMaxTextureFileBytes = 32u << 20;
inline constexpr int kMaxTextureSide = 4096;

struct Texture {
  int width = 0, height = 0;
  // three planes (R, then G, then B) of width x height values in 0..1, row 0 the image's top
  // (texture coordinate v = 1), the byte value / 255: a reflectance, as albedo is
  std::vector<float> rgb;
  std::string file;  // where it was read from, for messages
};

// Reads a PNG texture (8 or 16 bits, grey, RGB or RGBA: alpha ignored). Throws MeshError
// ("<file>: <what is wrong>") for a file that is not a regular file of at most
// kMaxTextureFileBytes, not a PNG, or whose header claims a side over kMaxTextureSide (checked
// before any pixel is decoded).
Texture load_texture(const std::filesystem::path& file);

// The texel nearest to texture coordinates (u, v), repeated beyond [0, 1) (the renderer's rule,
// for tests): R, G, B.
void texel_at(const Texture& t, double u, double v, float out[3]);

}  // namespace sim
