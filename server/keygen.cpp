// cslam-keygen: makes ZeroMQ CURVE key pairs for cslam-server and its robots (docs/security.md).
//   cslam-keygen --out keys/server                 -> keys/server.key (secret) + keys/server.pub
//   cslam-keygen --out keys/robot1 --client-ids 1  -> robot1.pub bound to client id 1
// Copy the server's .pub to every robot (--server-key), each robot's .pub into the server's
// --clients-allowed folder; .key files never leave their machine.
#include <filesystem>
#include <iostream>

#include "core/cli.h"
#include "core/error.h"
#include "proto/keys/curve_keys.h"

namespace {

int run(int argc, char** argv) {
  cslam::CliArgs cli("cslam-keygen", "Makes a CURVE key pair: OUT.key (secret, mode 0600) and OUT.pub (public).");
  cli.option("out", "path prefix of the two files (OUT.key, OUT.pub)")
      .option("client-ids", "comma-separated client ids the key may say hello as (default: any)", "")
      .flag("force", "overwrite existing files");
  if (!cli.parse(argc, argv)) return 0;
  const std::string out = cli.get("out");
  const std::set<cslam::ClientId> ids = cli.get("client-ids").empty()
                                            ? std::set<cslam::ClientId>{}
                                            : cslam::auth::parse_client_ids(cli.get("client-ids"), "--client-ids");
  const std::string key_file = out + ".key", pub_file = out + ".pub";
  if (!cli.flag_set("force") && (std::filesystem::exists(key_file) || std::filesystem::exists(pub_file)))
    throw cslam::ConfigError("cslam-keygen: " + key_file + " or " + pub_file + " exists (use --force to overwrite)");
  const auto parent = std::filesystem::path(out).parent_path();
  if (!parent.empty()) std::filesystem::create_directories(parent);
  const cslam::auth::CurveKeyPair keys = cslam::auth::generate_keypair();
  cslam::auth::write_secret_file(key_file, keys);
  cslam::auth::write_public_file(pub_file, keys.public_key, ids);
  std::cout << "wrote " << key_file << " (secret) and " << pub_file << " (public key " << keys.public_key << ")\n";
  return 0;
}

}  // namespace

int main(int argc, char** argv) { return cslam::run_main("cslam-keygen", argc, argv, run); }
