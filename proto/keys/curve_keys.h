#pragma once
// ZeroMQ CURVE key files (rfc.zeromq.org 26): Z85 text keys made by cslam-keygen.
//   NAME.key (secret, mode 0600):  public-key = <40 Z85 chars>   secret-key = <40 Z85 chars>
//   NAME.pub (for the peer):       public-key = <40 Z85 chars>   [client-ids = 1,2,...]
// Lines are `key = value`, a line starting with '#' is a comment (Z85 keys may contain '#'); an unknown key or a
// malformed value is an error naming the file. A server's --clients-allowed DIR holds one *.pub file per robot; its
// optional client-ids bind the key to those ids (the ids it may say hello as).
#include <map>
#include <set>
#include <string>
#include <vector>

#include "core/ids.h"

namespace cslam::auth {

struct CurveKeyPair {
  std::string public_key, secret_key;  // Z85, 40 characters each
};

struct AllowedKey {
  std::string public_key;         // Z85
  std::set<ClientId> client_ids;  // empty: any id
  std::string file;               // where it came from (for logs)
};

// Generates a key pair with libzmq (libsodium). Throws std::runtime_error if CURVE is unavailable.
CurveKeyPair generate_keypair();
// True if s is a 40-character Z85 key that decodes to 32 bytes.
bool valid_z85_key(const std::string& s);

// Writers (atomic: a temp file renamed over the target). The secret file gets mode 0600.
void write_secret_file(const std::string& path, const CurveKeyPair& keys);
void write_public_file(const std::string& path, const std::string& public_key, const std::set<ClientId>& ids);

// Readers; throw ConfigError naming the file and the problem.
CurveKeyPair read_secret_file(const std::string& path);
// A .pub file, or a .key file (its public key) for convenience.
AllowedKey read_public_file(const std::string& path);
// Every *.pub file of a folder (sorted by name). Throws ConfigError if none or a duplicate key.
std::vector<AllowedKey> read_allowed_dir(const std::string& dir);

// "1,2,5" -> {1,2,5}; throws ConfigError on anything else.
std::set<ClientId> parse_client_ids(const std::string& text, const std::string& source);

}  // namespace cslam::auth
