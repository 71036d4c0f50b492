#include "proto/keys/curve_keys.h"

#include <sys/stat.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <stdexcept>

#include <zmq.h>

#include "core/error.h"

namespace cslam::auth {

namespace {

std::string trim(const std::string& s) {
  const auto b = s.find_first_not_of(" \t\r");
  if (b == std::string::npos) return "";
  return s.substr(b, s.find_last_not_of(" \t\r") - b + 1);
}

std::map<std::string, std::string> read_key_values(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw ConfigError("cannot read key file " + path);
  std::map<std::string, std::string> kv;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    line = trim(line);
    if (line.empty() || line[0] == '#') continue;  // whole-line comments only: Z85 keys may contain '#'

    const auto eq = line.find('=');
    if (eq == std::string::npos)
      throw ConfigError("key file " + path + " line " + std::to_string(n) + ": expected 'name = value'");
    const std::string key = trim(line.substr(0, eq)), value = trim(line.substr(eq + 1));
    if (key != "public-key" && key != "secret-key" && key != "client-ids")
      throw ConfigError("key file " + path + " line " + std::to_string(n) + ": unknown key '" + key + "'");
    if (kv.count(key)) throw ConfigError("key file " + path + ": '" + key + "' given twice");
    kv[key] = value;
  }
  return kv;
}

void write_atomic(const std::string& path, const std::string& text, mode_t mode) {
  const std::string tmp = path + ".tmp";
  {
    std::ofstream out(tmp, std::ios::trunc);
    if (!out) throw ConfigError("cannot write " + tmp);
    ::chmod(tmp.c_str(), mode);
    out << text;
    if (!out.flush()) throw ConfigError("cannot write " + tmp);
  }
  ::chmod(tmp.c_str(), mode);
  std::filesystem::rename(tmp, path);
}

std::string ids_text(const std::set<ClientId>& ids) {
  std::string s;
  for (ClientId id : ids) s += (s.empty() ? "" : ",") + std::to_string(id);
  return s;
}

}  // namespace

CurveKeyPair generate_keypair() {
  if (!zmq_has("curve")) throw std::runtime_error("libzmq was built without CURVE support");
  char pub[41], sec[41];
  if (zmq_curve_keypair(pub, sec) != 0)
    throw std::runtime_error(std::string("zmq_curve_keypair: ") + zmq_strerror(zmq_errno()));
  return {pub, sec};
}

bool valid_z85_key(const std::string& s) {
  if (s.size() != 40) return false;
  std::uint8_t out[32];
  return zmq_z85_decode(out, s.c_str()) != nullptr;
}

std::set<ClientId> parse_client_ids(const std::string& text, const std::string& source) {
  std::set<ClientId> ids;
  std::stringstream ss(text);
  std::string item;
  while (std::getline(ss, item, ',')) {
    item = trim(item);
    std::size_t used = 0;
    long v = -1;
    try {
      v = std::stol(item, &used);
    } catch (const std::exception&) {
      used = 0;
    }
    if (item.empty() || used != item.size() || v < 0 || v > 65535)
      throw ConfigError(source + ": client-ids must be a comma-separated list of ids 0..65535, got '" + text + "'");
    ids.insert(ClientId(v));
  }
  return ids;
}

void write_secret_file(const std::string& path, const CurveKeyPair& keys) {
  write_atomic(path,
               "# cslam CURVE secret key: keep private (mode 0600)\npublic-key = " + keys.public_key +
                   "\nsecret-key = " + keys.secret_key + "\n",
               0600);
}

void write_public_file(const std::string& path, const std::string& public_key, const std::set<ClientId>& ids) {
  std::string text = "# cslam CURVE public key\npublic-key = " + public_key + "\n";
  if (!ids.empty()) text += "client-ids = " + ids_text(ids) + "\n";
  write_atomic(path, text, 0644);
}

CurveKeyPair read_secret_file(const std::string& path) {
  const auto kv = read_key_values(path);
  if (!kv.count("secret-key")) throw ConfigError("key file " + path + ": no secret-key (is it a .pub file?)");
  CurveKeyPair k;
  k.secret_key = kv.at("secret-key");
  if (!valid_z85_key(k.secret_key))
    throw ConfigError("key file " + path + ": secret-key is not a 40-character Z85 key");
  char pub[41];
  if (zmq_curve_public(pub, k.secret_key.c_str()) != 0) throw ConfigError("key file " + path + ": bad secret-key");
  k.public_key = pub;
  if (kv.count("public-key") && kv.at("public-key") != k.public_key)
    throw ConfigError("key file " + path + ": public-key does not belong to secret-key");
  return k;
}

AllowedKey read_public_file(const std::string& path) {
  const auto kv = read_key_values(path);
  if (!kv.count("public-key")) throw ConfigError("key file " + path + ": no public-key");
  AllowedKey a;
  a.public_key = kv.at("public-key");
  a.file = path;
  if (!valid_z85_key(a.public_key))
    throw ConfigError("key file " + path + ": public-key is not a 40-character Z85 key");
  if (kv.count("client-ids")) a.client_ids = parse_client_ids(kv.at("client-ids"), "key file " + path);
  return a;
}

std::vector<AllowedKey> read_allowed_dir(const std::string& dir) {
  if (!std::filesystem::is_directory(dir)) throw ConfigError("--clients-allowed: " + dir + " is not a folder");
  std::vector<std::string> files;
  for (const auto& e : std::filesystem::directory_iterator(dir))
    if (e.is_regular_file() && e.path().extension() == ".pub") files.push_back(e.path().string());
  std::sort(files.begin(), files.end());
  if (files.empty()) throw ConfigError("--clients-allowed: no *.pub key file in " + dir);
  std::vector<AllowedKey> keys;
  std::set<std::string> seen;
  for (const std::string& f : files) {
    keys.push_back(read_public_file(f));
    if (!seen.insert(keys.back().public_key).second) throw ConfigError("--clients-allowed: " + f + " repeats a key");
  }
  return keys;
}

}  // namespace cslam::auth
