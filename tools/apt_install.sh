# Sourced by tools/setup.sh and tools/sanitize.sh: install_missing PREFIX PACKAGE... installs
# (as root, non-interactively) those Debian packages that are not installed yet.
install_missing() {
  local prefix=$1 p
  shift
  local missing=()
  for p in "$@"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
  done
  if [ ${#missing[@]} -gt 0 ]; then
    echo "$prefix: installing ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get update -qq
    apt-get install -y -qq --no-install-recommends "${missing[@]}" < /dev/null
  fi
}
