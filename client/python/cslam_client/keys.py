"""CURVE keys for the robot's connection (ZeroMQ CURVE encryption and authentication), read
from the files cslam-keygen writes (docs/security.md)."""
from dataclasses import dataclass

import zmq


@dataclass
class CurveKeys:
    """ZeroMQ CURVE keys, Z85 text (40 characters), as cslam-keygen and zmq.curve_keypair() make."""
    server_public: str
    client_public: str
    client_secret: str

    @staticmethod
    def load(server_key_file, client_secret_file):
        """cslam-client's --server-key and --curve-secret files: the server's NAME.pub (or .key) and
        this robot's NAME.key (``public-key = ...`` / ``secret-key = ...`` lines; a file holding
        just the key works too). The robot's public key is derived if its file lacks it."""
        server = read_key_file(server_key_file)
        own = read_key_file(client_secret_file)
        server_public = server.get("public-key") or server.get("key")
        secret = own.get("secret-key") or own.get("key")
        if not server_public:
            raise ValueError(f"{server_key_file}: no public-key")
        if not secret:
            raise ValueError(f"{client_secret_file}: no secret-key (give this robot's .key file, not a .pub)")
        public = own.get("public-key") if "secret-key" in own else None
        return CurveKeys(server_public, public or zmq.curve_public(secret.encode()).decode(), secret)

    def apply(self, socket):
        socket.curve_serverkey = self.server_public.encode()
        socket.curve_publickey = self.client_public.encode()
        socket.curve_secretkey = self.client_secret.encode()


def read_key_file(path):
    """{'public-key': ..., 'secret-key': ..., 'client-ids': ...} from a cslam-keygen key file
    (``key = value`` lines, '#' comment lines; Z85 may contain '=' and '#', so only the first '='
    of a known key splits). A file holding one bare 40-character key gives {'key': KEY}."""
    values = {}
    with open(path) as f:
        lines = [line.strip() for line in f]
    for line in lines:
        if not line or line.startswith("#"):
            continue
        name, sep, value = line.partition("=")
        if sep and name.strip() in ("public-key", "secret-key", "client-ids"):
            values[name.strip()] = value.strip().strip('"')
        elif len(line) == 40 and not values:
            values = {"key": line}
        else:
            raise ValueError(f"{path}: unexpected line '{line[:20]}...' (expected 'public-key = KEY' lines)")
    for key in ("public-key", "secret-key", "key"):
        if key in values and len(values[key]) != 40:
            raise ValueError(f"{path}: {key} is not a 40-character Z85 key")
    return values
