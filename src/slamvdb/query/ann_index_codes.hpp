#pragma once
// The compact codes the ANN index (ann_index.hpp) scans: each unit embedding quantised to one byte
// per dimension (SQ8: per-dimension range learnt from the k-means sample), stored list by list so
// that a probed list is one contiguous run of memory. A question becomes integer weights, and a
// code's approximate score is an integer dot product (AVX2 when the CPU has it): only the order of
// these scores matters, since the best few are scored again exactly from the map.
#include <cstddef>
#include <cstdint>
#include <vector>

namespace slamvdb::ann_codes {

class Sq8Codebook {
 public:
  Sq8Codebook() = default;
  // Ranges of each dimension over `rows` (n x dim floats, row-major).
  Sq8Codebook(const float* rows, std::size_t n, std::size_t dim);
  std::size_t dim() const { return low_.size(); }
  // Bytes per code: dim rounded up to 16 (zero padding), so the kernel needs no tail.
  std::size_t stride() const { return (dim() + 15) / 16 * 16; }
  // code[d] = round((x[d] - low[d]) / step[d]) clamped to 0..255; `code` holds stride() bytes.
  void encode(const float* x, uint8_t* code) const;
  // Integer weights (stride() values) whose dot product with a code orders codes as the dot
  // product of `unit_query` with the vectors they stand for (low[] adds the same to every code).
  std::vector<int16_t> weights(const float* unit_query) const;

 private:
  std::vector<float> low_, step_;
};

// out[i] = sum_d codes[i * stride + d] * weights[d] for `count` codes (no overflow for dim <= 2048).
void score_codes(const uint8_t* codes, std::size_t count, std::size_t stride, const int16_t* weights, int32_t* out);

}  // namespace slamvdb::ann_codes
