#include "mvtwin/studies/report.h"

#include <cmath>
#include <cstdio>
#include <fstream>
#include <sstream>

#include "mvtwin/core/atomic_file.h"
#include "mvtwin/core/error.h"
#include "mvtwin/core/version.h"

namespace mvtwin::studies {
namespace {

std::string escape(const std::string& s) {
  std::string o;
  for (char c : s) {
    switch (c) {
      case '&':
        o += "&amp;";
        break;
      case '<':
        o += "&lt;";
        break;
      case '>':
        o += "&gt;";
        break;
      case '"':
        o += "&quot;";
        break;
      default:
        o += c;
    }
  }
  return o;
}

/// Escaped text with `code` and **bold** turned into HTML.
std::string inline_html(const std::string& s) {
  std::string e = escape(s), o;
  bool code = false, bold = false;
  for (std::size_t i = 0; i < e.size(); ++i) {
    if (e[i] == '`') {
      o += code ? "</code>" : "<code>";
      code = !code;
    } else if (!code && e.compare(i, 2, "**") == 0) {
      o += bold ? "</b>" : "<b>";
      bold = !bold;
      ++i;
    } else {
      o += e[i];
    }
  }
  if (code) o += "</code>";
  if (bold) o += "</b>";
  return o;
}

std::string base64(const std::string& in) {
  static const char* t = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
  std::string o;
  std::size_t i = 0;
  for (; i + 2 < in.size(); i += 3) {
    const unsigned v = (static_cast<unsigned char>(in[i]) << 16) |
                       (static_cast<unsigned char>(in[i + 1]) << 8) |
                       static_cast<unsigned char>(in[i + 2]);
    o += t[v >> 18];
    o += t[(v >> 12) & 63];
    o += t[(v >> 6) & 63];
    o += t[v & 63];
  }
  if (i < in.size()) {
    unsigned v = static_cast<unsigned char>(in[i]) << 16;
    if (i + 1 < in.size()) v |= static_cast<unsigned char>(in[i + 1]) << 8;
    o += t[v >> 18];
    o += t[(v >> 12) & 63];
    o += i + 1 < in.size() ? t[(v >> 6) & 63] : '=';
    o += '=';
  }
  return o;
}

void write_text(const std::filesystem::path& path, const std::string& text) {
  write_atomically(path, [&](const std::filesystem::path& tmp) {
    std::ofstream f(tmp, std::ios::binary);
    f << text;
    f.close();
    if (!f) throw Error(path.string() + ": write failed");
  });
}

}  // namespace

void Report::heading(const std::string& text) {
  blocks_.push_back({Block::kHeading, text, {}, {}, {}});
}
void Report::paragraph(const std::string& text) {
  blocks_.push_back({Block::kParagraph, text, {}, {}, {}});
}
void Report::table(const std::vector<std::string>& header,
                   const std::vector<std::vector<std::string>>& rows) {
  blocks_.push_back({Block::kTable, "", "", header, rows});
}
void Report::figure(const std::string& png, const std::string& caption) {
  blocks_.push_back({Block::kFigure, png, caption, {}, {}});
}
void Report::code(const std::string& text) { blocks_.push_back({Block::kCode, text, {}, {}, {}}); }

void Report::how_made(const std::string& command, const std::string& workers, double wall_s) {
  heading("How this was made");
  code(command.empty() ? "(library call)" : command);
  paragraph("mvtwin " + std::string(kVersion) + ", " + workers + ", " + number(wall_s, 0) +
            " s wall time (this run; what a resumed run had finished is not redone).");
}

void Report::write(const std::filesystem::path& dir) const {
  std::ostringstream md, html;
  md << "# " << title_ << "\n\n";
  html << "<!DOCTYPE html>\n<html><head><meta charset=\"utf-8\"><title>" << escape(title_)
       << "</title>\n<style>body{font-family:sans-serif;max-width:1000px;margin:2em auto;"
          "line-height:1.45}table{border-collapse:collapse;margin:1em 0}td,th{border:1px solid "
          "#bbb;padding:3px 8px;text-align:right}th{background:#eee}td:first-child{text-align:"
          "left}img{max-width:100%}pre{background:#f4f4f4;padding:8px;overflow-x:auto}"
          "figcaption{font-size:90%;color:#444}</style></head><body>\n<h1>"
       << escape(title_) << "</h1>\n";
  for (const Block& b : blocks_) {
    switch (b.kind) {
      case Block::kHeading:
        md << "## " << b.text << "\n\n";
        html << "<h2>" << inline_html(b.text) << "</h2>\n";
        break;
      case Block::kParagraph:
        md << b.text << "\n\n";
        html << "<p>" << inline_html(b.text) << "</p>\n";
        break;
      case Block::kCode:
        md << "```\n" << b.text << "\n```\n\n";
        html << "<pre>" << escape(b.text) << "</pre>\n";
        break;
      case Block::kTable: {
        md << "|";
        html << "<table><tr>";
        for (const auto& h : b.header) {
          md << " " << h << " |";
          html << "<th>" << inline_html(h) << "</th>";
        }
        md << "\n|";
        html << "</tr>\n";
        for (std::size_t i = 0; i < b.header.size(); ++i) md << (i == 0 ? "---|" : "---:|");
        md << "\n";
        for (const auto& r : b.rows) {
          md << "|";
          html << "<tr>";
          for (const auto& c : r) {
            md << " " << c << " |";
            html << "<td>" << inline_html(c) << "</td>";
          }
          md << "\n";
          html << "</tr>\n";
        }
        md << "\n";
        html << "</table>\n";
        break;
      }
      case Block::kFigure: {
        md << "![" << b.caption << "](" << b.text << ")\n\n*" << b.caption << "*\n\n";
        std::ifstream f(dir / b.text, std::ios::binary);
        std::string data((std::istreambuf_iterator<char>(f)), std::istreambuf_iterator<char>());
        html << "<figure><img alt=\"" << escape(b.caption) << "\" src=\""
             << (data.empty() ? escape(b.text) : "data:image/png;base64," + base64(data))
             << "\"><figcaption>" << inline_html(b.caption) << "</figcaption></figure>\n";
        break;
      }
    }
  }
  html << "</body></html>\n";
  write_text(dir / "report.md", md.str());
  write_text(dir / "report.html", html.str());
}

std::string number(double v, int digits) {
  if (!std::isfinite(v)) return "n/a";
  char s[64];
  std::snprintf(s, sizeof s, "%.*f", digits, v);
  return s;
}

std::string mean_sd(double mean, double sd, int digits) {
  if (!std::isfinite(mean)) return "n/a";
  return number(mean, digits) + " ± " + number(sd, digits);
}

}  // namespace mvtwin::studies
