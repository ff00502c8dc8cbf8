#pragma once
// A confusion matrix as a picture: rows are ground-truth classes (ignored classes left out),
// columns the predicted classes (plus the ignored classes and "none" when something was predicted
// as them), each cell coloured by its share of the row (so the diagonal is the recall), labelled
// with the count and the share, and a colour bar for the shares.
#include <filesystem>
#include <opencv2/core.hpp>
#include <string>

#include "slamvdb/eval/confusion_matrix.hpp"

namespace slamvdb {

// BGR image, ready for cv::imwrite.
cv::Mat render_confusion_matrix(const ConfusionMatrix& matrix, const std::string& title = {});
// Throws Error naming the file if it cannot be written.
void write_confusion_png(const std::filesystem::path& file, const ConfusionMatrix& matrix,
                         const std::string& title = {});

}  // namespace slamvdb
