// The server's request decoding (server/request_decoding.hpp): the whole input as a POST /api/query
// body for a 4-d map. A request is decoded or refused with RequestError (an Error); a decoded one
// must hold what the limits promise: at most max_terms terms, texts within max_text_bytes, vectors
// of the map's dimension with finite values, top_k within 1..max_top_k.
#include <cmath>
#include <cstdlib>
#include <string_view>

#include "slamvdb/core/error.hpp"
#include "slamvdb/server/request_decoding.hpp"

extern "C" int LLVMFuzzerTestOneInput(const uint8_t* data, size_t size) {
  const std::string_view body(reinterpret_cast<const char*>(data), size);
  slamvdb::ServerLimits limits;
  limits.max_terms = 8;
  limits.max_text_bytes = 64;
  limits.max_top_k = 1000;
  try {
    const slamvdb::QueryRequest r = slamvdb::decode_query_request(body, 4, limits);
    const auto& t = r.terms;
    const std::size_t terms = t.text.size() + t.not_text.size() + t.classes.size() + t.not_classes.size() +
                              t.vectors.size() + t.not_vectors.size();
    if (terms > limits.max_terms || !t.has_positive()) std::abort();
    for (const auto* texts : {&t.text, &t.not_text, &t.classes, &t.not_classes})
      for (const auto& s : *texts)
        if (s.empty() || s.size() > limits.max_text_bytes) std::abort();
    for (const auto* vectors : {&t.vectors, &t.not_vectors})
      for (const auto& v : *vectors)
        if (v.size() != 4 || !v.allFinite()) std::abort();
    if (r.search.top_k < 1 || r.search.top_k > limits.max_top_k) std::abort();
  } catch (const slamvdb::Error&) {
  }
  return 0;
}
