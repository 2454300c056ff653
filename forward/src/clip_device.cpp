#include "mvtwin/forward/clip_device.h"

#include <algorithm>
#include <cctype>

#include <nlohmann/json.hpp>

#include "clip_devices_data.h"
#include "mvtwin/core/error.h"

namespace mvtwin::forward {

const std::vector<ClipDevice>& clip_devices() {
  static const std::vector<ClipDevice> table = [] {
    std::vector<ClipDevice> out;
    const nlohmann::json j = nlohmann::json::parse(kClipDevicesJson);
    for (const auto& d : j.at("devices")) {
      ClipDevice c;
      c.name = d.at("name").get<std::string>();
      c.family = d.at("family").get<std::string>();
      c.maker = d.at("maker").get<std::string>();
      c.grasp = d.at("grasp").get<std::string>();
      c.width_mm = d.at("width_mm").get<double>();
      c.arm_length_mm = d.at("arm_length_mm").get<double>();
      c.spacer_mm = d.at("spacer_mm").get<double>();
      c.verified = d.at("verified").get<bool>();
      c.source = d.at("source").get<std::string>();
      out.push_back(std::move(c));
    }
    return out;
  }();
  return table;
}

const ClipDevice& clip_device(std::string_view name) {
  auto lower = [](std::string_view s) {
    std::string o(s);
    std::transform(o.begin(), o.end(), o.begin(), [](unsigned char c) { return std::tolower(c); });
    return o;
  };
  std::string known;
  for (const ClipDevice& d : clip_devices()) {
    if (lower(d.name) == lower(name)) return d;
    known += (known.empty() ? "" : ", ") + d.name;
  }
  throw Error("unknown clip device '" + std::string(name) + "' (known: " + known + ")");
}

}  // namespace mvtwin::forward
