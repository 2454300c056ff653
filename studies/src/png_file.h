#pragma once
#include <cstdio>
#include <filesystem>
#include <vector>

#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"

namespace mvtwin::studies {

/// Writes an image as PNG atomically; throws mvtwin::Error naming the path.
inline void write_png(const std::filesystem::path& path, const cv::Mat& img) {
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::vector<uchar> buf;
    if (!cv::imencode(".png", img, buf)) throw Error(path.string() + ": PNG encoding failed");
    FILE* f = std::fopen(tmp.c_str(), "wb");
    if (!f) throw Error(path.string() + ": cannot write");
    const bool ok = std::fwrite(buf.data(), 1, buf.size(), f) == buf.size();
    if (std::fclose(f) != 0 || !ok) throw Error(path.string() + ": write failed");
  });
}

}  // namespace mvtwin::studies
