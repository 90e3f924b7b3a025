#include "core/config.hpp"

#include <filesystem>
#include <fstream>
#include <sstream>

#include <toml++/toml.h>

#include "core/error.hpp"

namespace cd {

struct Section::Impl {
  std::shared_ptr<toml::table> root;  // keeps the parsed document alive
  const toml::table* table = nullptr;  // null for an absent section
  std::string file;
  std::string prefix;  // "world." or ""
  mutable std::set<std::string> used;
};

namespace {

[[noreturn]] void fail(const Section& s, std::string_view key, const std::string& what) {
  throw ConfigError(s.file() + ": " + s.key_path(key) + ": " + what);
}

const toml::node* lookup(const Section::Impl& impl, std::string_view key) {
  impl.used.insert(std::string(key));
  return impl.table ? impl.table->get(key) : nullptr;
}

std::string fmt_range(double lo, double hi) {
  std::ostringstream o;
  o << "[" << lo << ", " << hi << "]";
  return o.str();
}

}  // namespace

const std::string& Section::file() const { return impl_->file; }

std::string Section::key_path(std::string_view key) const {
  return impl_->prefix + std::string(key);
}

bool Section::has(std::string_view key) const {
  return impl_->table && impl_->table->contains(key);
}

double Section::number(std::string_view key, double fallback, double lo, double hi) const {
  const toml::node* n = lookup(*impl_, key);
  if (!n) return fallback;
  double v;
  if (auto f = n->value_exact<double>()) {
    v = *f;
  } else if (auto i = n->value_exact<int64_t>()) {
    v = static_cast<double>(*i);
  } else {
    fail(*this, key, "expected a number");
  }
  if (!(v >= lo && v <= hi)) fail(*this, key, "value out of range " + fmt_range(lo, hi));
  return v;
}

int64_t Section::integer(std::string_view key, int64_t fallback, int64_t lo, int64_t hi) const {
  const toml::node* n = lookup(*impl_, key);
  if (!n) return fallback;
  auto i = n->value_exact<int64_t>();
  if (!i) fail(*this, key, "expected an integer");
  if (*i < lo || *i > hi)
    fail(*this, key, "value out of range " + fmt_range(double(lo), double(hi)));
  return *i;
}

bool Section::boolean(std::string_view key, bool fallback) const {
  const toml::node* n = lookup(*impl_, key);
  if (!n) return fallback;
  auto b = n->value_exact<bool>();
  if (!b) fail(*this, key, "expected true or false");
  return *b;
}

std::string Section::string(std::string_view key, const std::string& fallback,
                            const std::vector<std::string>& allowed) const {
  const toml::node* n = lookup(*impl_, key);
  if (!n) return fallback;
  auto s = n->value_exact<std::string>();
  if (!s) fail(*this, key, "expected a string");
  if (!allowed.empty()) {
    bool ok = false;
    std::string list;
    for (const auto& a : allowed) {
      ok = ok || a == *s;
      list += (list.empty() ? "" : ", ") + a;
    }
    if (!ok) fail(*this, key, "'" + *s + "' is not one of: " + list);
  }
  return *s;
}

std::vector<std::string> Section::strings(std::string_view key,
                                          const std::vector<std::string>& fallback) const {
  const toml::node* n = lookup(*impl_, key);
  if (!n) return fallback;
  const toml::array* arr = n->as_array();
  if (!arr) fail(*this, key, "expected an array of strings");
  std::vector<std::string> out;
  for (const auto& el : *arr) {
    auto s = el.value_exact<std::string>();
    if (!s) fail(*this, key, "expected an array of strings");
    out.push_back(*s);
  }
  return out;
}

Section Section::section(std::string_view key) const {
  const toml::node* n = lookup(*impl_, key);
  Section s;
  s.impl_ = std::make_shared<Impl>();
  s.impl_->root = impl_->root;
  s.impl_->file = impl_->file;
  s.impl_->prefix = key_path(key) + ".";
  if (n) {
    s.impl_->table = n->as_table();
    if (!s.impl_->table) fail(*this, key, "expected a table [" + key_path(key) + "]");
  }
  return s;
}

void Section::finish() const {
  if (!impl_->table) return;
  for (const auto& [k, v] : *impl_->table) {
    if (!impl_->used.count(std::string(k.str()))) {
      throw ConfigError(impl_->file + ": unknown key '" + key_path(k.str()) + "'");
    }
  }
}

Section ConfigFile::parse(const std::string& text, const std::string& name) {
  Section s;
  s.impl_ = std::make_shared<Section::Impl>();
  s.impl_->file = name;
  try {
    s.impl_->root = std::make_shared<toml::table>(toml::parse(text, name));
  } catch (const toml::parse_error& e) {
    std::ostringstream o;
    o << name << ":" << e.source().begin.line << ":" << e.source().begin.column
      << ": malformed TOML: " << e.description();
    throw ConfigError(o.str());
  }
  s.impl_->table = s.impl_->root.get();
  return s;
}

Section ConfigFile::load(const std::string& path) {
  std::error_code ec;
  if (!std::filesystem::is_regular_file(path, ec)) {
    throw ConfigError(path + ": config file not found");
  }
  std::ifstream in(path, std::ios::binary);
  if (!in) throw ConfigError(path + ": cannot read config file");
  std::stringstream buf;
  buf << in.rdbuf();
  return parse(buf.str(), path);
}

}  // namespace cd
