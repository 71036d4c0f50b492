# cslam server image: Debian 12, the same install script as a bare machine.
FROM debian:bookworm
ENV DEBIAN_FRONTEND=noninteractive
WORKDIR /opt/cslam
COPY scripts/install-deps.sh scripts/install-deps.sh
RUN bash scripts/install-deps.sh && rm -rf /var/lib/apt/lists/*
COPY . .
RUN bash scripts/build.sh -DCSLAM_BUILD_TESTS=OFF
EXPOSE 5555 8080
# Starts the collaborative SLAM server (ZeroMQ on 5555, HTTP on 8080).
CMD ["build/bin/cslam-server", "--bind", "tcp://*:5555", "--http", "8080", "--http-bind", "0.0.0.0", "--out-dir", "/data/out"]
