# cslam server image, two stages (see docs/deployment.md):
#   build   - Debian 12 with the compilers; builds the programs and installs the viewer's pinned
#             three.js (scripts/install-web.sh, npm ci from web/package-lock.json);
#   runtime - Debian 12 with only the shared libraries the programs and their codec plugins load
#             (their ldd closure, copied from the build stage), the stripped programs, the codec
#             plugins (lib/cslam/, loaded on first use: src/codec/codec_plugins.h), the vocabulary
#             and the viewer.
# The paths under /opt/cslam are the same in both stages, so the programs find the vocabulary
# (data/vocabulary) and the viewer (web/) at their compiled-in defaults.
ARG BASE=debian:bookworm

FROM ${BASE} AS build
ENV DEBIAN_FRONTEND=noninteractive
WORKDIR /opt/cslam
COPY scripts/install-deps.sh scripts/install-web.sh scripts/
# A compiler cache bound at /ccache (podman build -v DIR:/ccache, see scripts/container-smoke.sh)
# is used when present; the image does not depend on it.
# (man1 exists for openjdk's postinst, which libpcl-dev pulls in, on bases trimmed like -slim.)
# npm: for scripts/install-web.sh (npm ci of the viewer's pinned three.js); openssl: the program
# shipped in the image to make the HTTP certificate (compose.yaml's keys service).
RUN mkdir -p /usr/share/man/man1 && bash scripts/install-deps.sh --build-only \
    && apt-get install -y -qq --no-install-recommends npm openssl \
    && if [ -d /ccache ]; then apt-get install -y -qq --no-install-recommends ccache; fi \
    && rm -rf /var/lib/apt/lists/*
COPY web/package.json web/package-lock.json web/
# CI=true: fail the build if npm ci fails (the image must serve three.js). Behind a TLS-inspecting
# proxy, pass its CA: --build-arg CSLAM_NPM_CA=/path with the file bound in (container-smoke.sh
# does this from NODE_EXTRA_CA_CERTS).
ARG CSLAM_NPM_CA=
RUN if [ -n "$CSLAM_NPM_CA" ]; then export NODE_EXTRA_CA_CERTS="$CSLAM_NPM_CA"; fi; CI=true bash scripts/install-web.sh
COPY . .
RUN if [ -d /ccache ] && command -v ccache > /dev/null; then \
      export CCACHE_DIR=/ccache CCACHE_BASEDIR=/opt/cslam CCACHE_COMPILERCHECK=content CMAKE_CXX_COMPILER_LAUNCHER=ccache; \
    fi; \
    bash scripts/build.sh -DCSLAM_BUILD_TESTS=OFF
# The programs a deployment runs (benchmarks stay out), stripped, with curl for the healthcheck and
# openssl for the HTTP certificate;
# then every shared library they load that the bare base image lacks, at its real path, with its
# Debian package's copyright file.
# OPTIONAL_PROGRAMS are shipped when the build has them (cslam-keygen comes with CURVE support).
ARG PROGRAMS="cslam-server cslam-client cslam-synth cslam-slam cslam-eval cslam-recon cslam-experiment cslam-vocab"
ARG OPTIONAL_PROGRAMS="cslam-keygen cslam-map"
RUN set -eu; mkdir -p /stage/opt/cslam/bin /stage/usr/local/bin; \
    for p in $PROGRAMS; do install -s -m 0755 build/bin/$p /stage/opt/cslam/bin/$p; done; \
    for p in $OPTIONAL_PROGRAMS; do if [ -f build/bin/$p ]; then install -s -m 0755 build/bin/$p /stage/opt/cslam/bin/$p; fi; done; \
    mkdir -p /stage/opt/cslam/lib/cslam; \
    for m in build/lib/cslam/*.so; do install -s -m 0644 "$m" /stage/opt/cslam/lib/cslam/; done; \
    install -m 0755 /usr/bin/curl /stage/usr/local/bin/curl; \
    install -m 0755 /usr/bin/openssl /stage/usr/local/bin/openssl; \
    mkdir -p /stage/etc/ssl /stage/usr/lib/ssl /stage/usr/share/doc/openssl; \
    cp /etc/ssl/openssl.cnf /stage/etc/ssl/; ln -s /etc/ssl/openssl.cnf /stage/usr/lib/ssl/openssl.cnf; \
    cp /usr/share/doc/openssl/copyright /stage/usr/share/doc/openssl/; \
    ldd /stage/opt/cslam/bin/* /stage/opt/cslam/lib/cslam/*.so /stage/usr/local/bin/curl /stage/usr/local/bin/openssl | awk '$2 == "=>" && $3 ~ /^\// {print $3}' | sort -u \
      > /tmp/libs.txt; \
    while read -r lib; do \
      real=$(readlink -f "$lib"); pkg=$(dpkg -S "$real" 2>/dev/null | head -1 | cut -d: -f1 || true); \
      if [ -n "$pkg" ] && [ "$(dpkg-query -W -f='${Priority}' "$pkg")" = required ]; then continue; fi; \
      dir=$(readlink -f "$(dirname "$lib")"); mkdir -p "/stage$dir"; cp -L "$lib" "/stage$dir/$(basename "$lib")"; \
      if [ -n "$pkg" ] && [ -f "/usr/share/doc/$pkg/copyright" ]; then \
        mkdir -p "/stage/usr/share/doc/$pkg"; cp "/usr/share/doc/$pkg/copyright" "/stage/usr/share/doc/$pkg/"; \
      fi; \
    done < /tmp/libs.txt; \
    mkdir -p /stage/opt/cslam/data/vocabulary /stage/opt/cslam/web/node_modules/three/build; \
    cp data/vocabulary/cslam_orb.voc data/vocabulary/README.md /stage/opt/cslam/data/vocabulary/; \
    cp web/index.html web/*.js /stage/opt/cslam/web/; \
    cp web/node_modules/three/build/three.module.js /stage/opt/cslam/web/node_modules/three/build/; \
    cp web/node_modules/three/LICENSE web/node_modules/three/package.json /stage/opt/cslam/web/node_modules/three/; \
    echo "[image] $(ls /stage/opt/cslam/bin | wc -l) programs, $(find /stage/usr -name '*.so*' | wc -l) libraries"

FROM ${BASE} AS runtime
COPY --from=build /stage/ /
RUN ldconfig && useradd --system --uid 10001 --home-dir /data --no-create-home cslam \
    && mkdir -p /data /keys && chown cslam:cslam /data /keys \
    && /opt/cslam/bin/cslam-server --help > /dev/null
ENV PATH=/opt/cslam/bin:$PATH
WORKDIR /data
VOLUME /data
USER cslam
EXPOSE 5555 8080
# The healthcheck asks over HTTPS with the token (given to curl on stdin, not on its command
# line); -k: it is this container's own loopback, the certificate may name other hosts.
HEALTHCHECK --interval=15s --timeout=5s --start-period=10s --retries=3 \
  CMD printf 'header = "Authorization: Bearer %s"\n' "$(cat /keys/http.token)" \
      | curl -sfk -o /dev/null -K - https://127.0.0.1:8080/api/status || exit 1
# ZeroMQ on 5555, HTTP API and viewer on 8080, results in /data/out.
# Keyed deployment (docs/security.md, docs/deployment.md): mount a folder with the server's key
# pair and the robots' public keys at /keys; ZeroMQ on 5555 then accepts only robots whose key is
# in /keys/clients (CURVE, encrypted). HTTP on 8080 is bound beyond the container's loopback, so it
# serves HTTPS with /keys/http.crt + /keys/http.key and needs the token in /keys/http.token on every
# API request (compose.yaml's keys service makes all of them; docs/security.md, "HTTP beyond
# loopback"). Without them the server refuses to start, saying which file is missing.
CMD ["cslam-server", "--bind", "tcp://*:5555", "--curve-secret", "/keys/server.key", "--clients-allowed", "/keys/clients", "--http", "8080", "--http-bind", "0.0.0.0", "--http-cert", "/keys/http.crt", "--http-key", "/keys/http.key", "--http-token-file", "/keys/http.token", "--out-dir", "/data/out"]
