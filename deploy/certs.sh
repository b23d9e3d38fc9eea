#!/usr/bin/env bash
# Certificates for a TRACE deployment across hosts (docs/deploy.md): one certificate authority,
# and per name a key and a certificate whose common name is the identity Zenoh's access control
# keys on (deploy/zenoh/two-hosts/*-router.json5). What this writes holds private keys: keep it
# on the hosts, never in the repository.
#
#   deploy/certs.sh DIR [NAME[=SAN,SAN...]]...
#
# DIR           where ca.pem, ca.key and NAME.pem, NAME.key go; an existing ca.pem/ca.key in
#               DIR is reused, so the script can be run again to add names.
# NAME          the common name: exec, lander_sim, station-a, monitor, lander-router, …
# SAN           extra names the holder is reached at, for a router its listening addresses:
#               an IPv4/IPv6 address or a DNS name (lander-router=10.0.0.1,lander).
#               Every certificate also names localhost and 127.0.0.1.
# Without names: lander-router=lander ground-router=ground exec lander_sim station-a monitor.
#
# Keys are EC P-256 in PKCS#8, certificates X.509 v3 for TLS server and client use (the
# routers are both), valid 825 days; the authority 10 years. Needs openssl.
set -euo pipefail

[ $# -ge 1 ] || { sed -n '2,17p' "$0" | sed 's/^# \{0,1\}//'; exit 2; }
dir=$1
shift
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(lander-router=lander ground-router=ground exec lander_sim station-a monitor)
command -v openssl >/dev/null || { echo "error: openssl not found (Debian package openssl)" >&2; exit 1; }
mkdir -p "$dir"
umask 077

key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; }

if [ ! -f "$dir/ca.pem" ] || [ ! -f "$dir/ca.key" ]; then
  key "$dir/ca.key"
  openssl req -x509 -new -key "$dir/ca.key" -sha256 -days 3650 -subj "/CN=TRACE deployment CA" \
    -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign" \
    -out "$dir/ca.pem"
  echo "authority: $dir/ca.pem"
fi

for item in "${names[@]}"; do
  name=${item%%=*}
  extra=
  [ "$item" = "$name" ] || extra=${item#*=}
  case $name in
    ''|*[!A-Za-z0-9._-]*) echo "error: $name: a name is letters, digits, '.', '_' and '-'" >&2; exit 2 ;;
  esac
  san="DNS:localhost,IP:127.0.0.1"
  IFS=, read -r -a alts <<<"$extra"
  for a in "${alts[@]}"; do
    [ -n "$a" ] || continue
    if [[ $a =~ ^[0-9.]+$ || $a == *:* ]]; then san+=",IP:$a"; else san+=",DNS:$a"; fi
  done
  key "$dir/$name.key"
  openssl req -new -key "$dir/$name.key" -subj "/CN=$name" -out "$dir/$name.csr"
  openssl x509 -req -in "$dir/$name.csr" -CA "$dir/ca.pem" -CAkey "$dir/ca.key" \
    -set_serial "0x$(openssl rand -hex 16)" -days 825 -sha256 -out "$dir/$name.pem" \
    -extfile <(printf '%s\n' "basicConstraints=critical,CA:FALSE" \
      "keyUsage=critical,digitalSignature" "extendedKeyUsage=serverAuth,clientAuth" \
      "subjectAltName=$san") 2>/dev/null
  rm -f "$dir/$name.csr"
  echo "$name: $dir/$name.pem ($san)"
done
