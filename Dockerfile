# cslam server image: Debian 12, the same install script as a bare machine.
FROM debian:bookworm
ENV DEBIAN_FRONTEND=noninteractive
WORKDIR /opt/cslam
COPY scripts/install-deps.sh scripts/install-deps.sh
RUN bash scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
COPY . .
RUN bash scripts/build.sh -DCSLAM_BUILD_TESTS=OFF
EXPOSE 5555 8080
# Keyed deployment (docs/security.md): mount a folder with the server's key pair and the robots'
# public keys, e.g.
#   docker run --rm -v $PWD/keys:/keys cslam build/bin/cslam-keygen --out /keys/server
#   (on each robot: cslam-keygen --out robot1 --client-ids 1; copy robot1.pub to keys/clients/)
#   docker run -v $PWD/keys:/keys -v $PWD/out:/data/out -p 5555:5555 -p 8080:8080 cslam
# ZeroMQ on 5555 accepts only robots whose key is in /keys/clients (CURVE, encrypted); HTTP on 8080.
CMD ["build/bin/cslam-server", "--bind", "tcp://*:5555", "--curve-secret", "/keys/server.key", \
     "--clients-allowed", "/keys/clients", "--http", "8080", "--http-bind", "0.0.0.0", "--out-dir", "/data/out"]
