# The `marvin` binary and the files its worlds name, for the cluster recipes of docs/SCALE.md
# (the Kubernetes Indexed Job in deploy/k8s/ runs this image).
#
#   docker build --build-arg MARVIN_COMMIT=$(git rev-parse --short=12 HEAD) -t marvin .
#   docker run --rm marvin eval run worlds/widgets.toml --scenes 4 --seed 370001
#
# MARVIN_COMMIT stamps the binary's code version (the records' `version`: `eval merge` refuses
# to mix versions); .git is not sent to the build. Built without rerun recordings (no viewer on
# a cluster node), which is several minutes shorter.

FROM rust:1.95-bookworm AS build
WORKDIR /src
COPY . .
ARG MARVIN_COMMIT=unknown
ENV MARVIN_COMMIT=${MARVIN_COMMIT}
RUN cargo build --release --locked --no-default-features --bin marvin

FROM debian:bookworm-slim
COPY --from=build /src/target/release/marvin /usr/local/bin/marvin
# The worlds, the robot's URDF (which the worlds name by relative path) and the model library
# (read at run time, from where MARVIN_MODELS says).
COPY worlds /opt/marvin/worlds
COPY urdf /opt/marvin/urdf
COPY mesh/models /opt/marvin/models
ENV MARVIN_MODELS=/opt/marvin/models
WORKDIR /opt/marvin
# Not root on a cluster: results go to a volume the Job mounts at /results.
RUN useradd --uid 1000 --create-home marvin && mkdir /results && chown marvin /results
USER marvin
ENTRYPOINT ["marvin"]
