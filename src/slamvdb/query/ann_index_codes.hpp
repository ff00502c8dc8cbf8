#pragma once
// The compact codes the ANN index (ann_index.hpp) scans: each cell's residual (its unit embedding
// minus its list's centroid) quantised to one byte per dimension (SQ8, per list and dimension the
// range of the list's residuals), split into two planes of 4 bits per dimension: the coarse
// plane (high nibbles) is what a question streams through for every probed cell, the fine plane
// (low nibbles) is read only for the few best of that pass, to order them by the whole 8-bit code.
// A question becomes integer weights, and a code's approximate score an integer dot product
// (AVX-512 VNNI or AVX2 when the CPU has them, chosen at run time; scalar otherwise: all give the
// same integers). Only the order matters: the best few are scored again exactly from the map.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace slamvdb::ann_codes {

// A question's weights for one codebook: its dot product with the vector a code stands for is
// about offset + unit * (the integer dot product of the weights with the code).
struct QueryWeights {
  std::vector<int8_t> coarse;  // stride() values (|w| <= 127): weights of the high nibbles
  float coarse_unit = 0, coarse_offset = 0;
  float coarse_most = 0;  // the largest coarse score of any code: offset + unit * sum of max(0, 15 w)
  std::vector<int16_t> fine;  // stride() values: weights of the whole 8-bit codes
  float fine_unit = 0, fine_offset = 0;
};

class Sq8Codebook {
 public:
  Sq8Codebook() = default;
  // Ranges of each dimension over `rows` (n x dim floats, row-major).
  Sq8Codebook(const float* rows, std::size_t n, std::size_t dim);
  // Each dimension's range [low[d], high[d]].
  Sq8Codebook(const std::vector<float>& low, const std::vector<float>& high);
  std::size_t dim() const { return low_.size(); }
  // Dimensions of a code: dim rounded up to 128 (zero padding), so that the kernels need no tail.
  std::size_t stride() const { return (dim() + 127) / 128 * 128; }
  // Bytes of one plane of a code (4 bits per dimension).
  std::size_t plane_bytes() const { return stride() / 2; }
  // c[d] = round((x[d] - low[d]) / step[d]) clamped to 0..255, its high nibble packed into `coarse`
  // and its low nibble into `fine` (plane_bytes() each; packing: see score_nibbles).
  void encode(const float* x, uint8_t* coarse, uint8_t* fine) const;
  QueryWeights weights(const float* unit_query) const;

 private:
  std::vector<float> low_, step_;
};

// Nibble packing of a plane: dimension 128 b + j (j < 64) is the low nibble of byte 64 b + j,
// dimension 128 b + 64 + j its high nibble (so a 64-byte load gives 128 dimensions in two runs).
// out[i] = sum_d nibble_d(plane i) * weights[d] for `count` planes of `plane_bytes` (a multiple of 64)
// bytes each; weights holds 2 * plane_bytes values.
void score_nibbles(const uint8_t* planes, std::size_t count, std::size_t plane_bytes, const int8_t* weights,
                   int32_t* out);
// The 8-bit code (2 * plane_bytes bytes, dimension order) of a code's two planes.
void join_planes(const uint8_t* coarse, const uint8_t* fine, std::size_t plane_bytes, uint8_t* code);
// out[i] = sum_d codes[i * stride + d] * weights[d] for `count` codes (no overflow for dim <= 2048).
void score_codes(const uint8_t* codes, std::size_t count, std::size_t stride, const int16_t* weights, int32_t* out);

// Every implementation of score_nibbles and join_planes, for the test that holds them to the
// definitions on this CPU.
using ScoreNibbles = void (*)(const uint8_t*, std::size_t, std::size_t, const int8_t*, int32_t*);
using JoinPlanes = void (*)(const uint8_t*, const uint8_t*, std::size_t, uint8_t*);
struct NibbleKernel {
  const char* name;
  bool supported;  // by this CPU
  ScoreNibbles score;
  JoinPlanes join;
};
std::vector<NibbleKernel> nibble_kernels();

}  // namespace slamvdb::ann_codes
