# Sourced by the scripts: one fixed build folder, kept between runs on a machine
# (a cold build of the dependencies takes minutes on 2 cores).
export CARGO_TARGET_DIR="${CARGO_TARGET_DIR:-/var/tmp/probecal-target}"
