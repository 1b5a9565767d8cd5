#!/usr/bin/env bash
# make-certs.sh: a certificate authority and one certificate per role of a panostereo site.
#
# Usage:
#   deploy/security/make-certs.sh [--out DIR] [--host NAME]... [--sensors "c1 c2"] \
#       [--managers "m1"] [--agents "a1"] [--days N] [--ca-name NAME] [--force]
#
# Writes, under DIR (default deploy/security/generated, which git ignores):
#   ca.pem, ca.key                      the site CA (ECDSA P-256, CA:TRUE, keyCertSign)
#   router.pem, router.key              the zenoh router's certificate (CN=router)
#   sensor-<id>.pem, sensor-<id>.key    one per sensor node (CN=sensor-<id>)
#   manager-<id>.pem, manager-<id>.key  one per resource manager (CN=manager-<id>)
#   agent-<id>.pem, agent-<id>.key      one per user agent (CN=agent-<id>)
#
# Every leaf is signed by the CA, CA:FALSE, extendedKeyUsage serverAuth+clientAuth, with a
# PKCS#8 key (what rustls, zenoh's TLS stack, reads) and subjectAltName DNS:localhost,
# IP:127.0.0.1 plus each --host (a name or an IPv4/IPv6 address). The common name is the
# identity the router's access-control rules match (`cert_common_names`), so a sensor's
# certificate can only ever publish that sensor's keys: see README.md beside this script.
#
# An existing CA in DIR is reused (so new leaves join the same site) unless --force.
set -euo pipefail

out="deploy/security/generated"
days=825
ca_name="panostereo-ca"
sensors=""
managers="m1"
agents="a1"
hosts=()
force=0

usage() { sed -n '2,22p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "make-certs.sh: error: $*" >&2; exit 1; }

while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) [[ $# -ge 2 ]] || die "--out needs a directory"; out="$2"; shift 2 ;;
    --host) [[ $# -ge 2 ]] || die "--host needs a name or address"; hosts+=("$2"); shift 2 ;;
    --sensors) [[ $# -ge 2 ]] || die "--sensors needs a list of ids"; sensors="$2"; shift 2 ;;
    --managers) [[ $# -ge 2 ]] || die "--managers needs a list of ids"; managers="$2"; shift 2 ;;
    --agents) [[ $# -ge 2 ]] || die "--agents needs a list of ids"; agents="$2"; shift 2 ;;
    --days) [[ $# -ge 2 ]] || die "--days needs a number"; days="$2"; shift 2 ;;
    --ca-name) [[ $# -ge 2 ]] || die "--ca-name needs a name"; ca_name="$2"; shift 2 ;;
    --force) force=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) die "unknown option '$1' (expected --out, --host, --sensors, --managers, --agents, --days, --ca-name, --force)" ;;
  esac
done

command -v openssl >/dev/null || die "openssl is not installed (apt-get install openssl)"
[[ "$days" =~ ^[0-9]+$ && "$days" -gt 0 ]] || die "--days must be a positive integer, got '$days'"
id_re='^[a-z0-9][a-z0-9-]*$'
for id in $sensors $managers $agents; do
  [[ "$id" =~ $id_re && ${#id} -le 48 ]] || die "ids must match [a-z0-9][a-z0-9-]* (at most 48 characters), got '$id'"
done
host_re='^[A-Za-z0-9.:-]+$'
for h in "${hosts[@]+"${hosts[@]}"}"; do
  [[ "$h" =~ $host_re ]] || die "--host must be a DNS name or an IP address, got '$h'"
done

mkdir -p "$out"
chmod 700 "$out"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT

# subjectAltName: localhost and 127.0.0.1 always, then each --host as IP or DNS.
san="DNS:localhost,IP:127.0.0.1"
for h in "${hosts[@]+"${hosts[@]}"}"; do
  if [[ "$h" =~ ^[0-9.]+$ || "$h" == *:* ]]; then san+=",IP:$h"; else san+=",DNS:$h"; fi
done

if [[ $force -eq 1 || ! -s "$out/ca.pem" || ! -s "$out/ca.key" ]]; then
  openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$out/ca.key" 2>/dev/null
  openssl req -new -x509 -key "$out/ca.key" -sha256 -days "$days" -subj "/CN=$ca_name" \
    -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign" \
    -addext "subjectKeyIdentifier=hash" \
    -out "$out/ca.pem"
  chmod 600 "$out/ca.key"
fi

leaf() {  # leaf NAME: NAME.key (PKCS#8) and NAME.pem signed by the CA, CN=NAME
  local name="$1"
  openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$out/$name.key" 2>/dev/null
  chmod 600 "$out/$name.key"
  cat >"$tmp/$name.ext" <<EOF
basicConstraints=critical,CA:FALSE
keyUsage=critical,digitalSignature,keyEncipherment
extendedKeyUsage=serverAuth,clientAuth
subjectAltName=$san
authorityKeyIdentifier=keyid
subjectKeyIdentifier=hash
EOF
  openssl req -new -key "$out/$name.key" -subj "/CN=$name" -out "$tmp/$name.csr"
  openssl x509 -req -in "$tmp/$name.csr" -CA "$out/ca.pem" -CAkey "$out/ca.key" -CAcreateserial \
    -CAserial "$tmp/ca.srl" -days "$days" -sha256 -extfile "$tmp/$name.ext" -out "$out/$name.pem" 2>/dev/null
  openssl verify -CAfile "$out/ca.pem" "$out/$name.pem" >/dev/null || die "certificate $name does not verify"
}

leaf router
for id in $sensors; do leaf "sensor-$id"; done
for id in $managers; do leaf "manager-$id"; done
for id in $agents; do leaf "agent-$id"; done

echo "make-certs.sh: CA '$ca_name' and certificates for router, sensors [${sensors}], managers [${managers}], agents [${agents}] in $out (SAN $san)"
