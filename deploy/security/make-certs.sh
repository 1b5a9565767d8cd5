#!/usr/bin/env bash
# make-certs.sh: a certificate authority and one certificate per role of a panostereo site.
#
# Usage:
#   deploy/security/make-certs.sh [--out DIR] [--host NAME]... [--sensors "c1 c2"] \
#       [--managers "m1"] [--agents "a1"] [--days N] [--ca-days N] [--ca-name NAME] \
#       [--renew "NAME..."] [--force]
#
# Issues the CA, the router's certificate and exactly the identities named (none by default).
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
# An existing CA in DIR is reused (so new leaves join the same site) unless --force, and so is
# every existing certificate that verifies under it: adding a camera (--sensors newcam) issues
# sensor-newcam only and re-keys nobody else. --renew "router agent-a1" re-issues those (new
# keys; e.g. the router's after a --host change). Leaves live --days (825) but never past the
# CA (--ca-days, 3650): a leaf that would outlive it is cut to the CA's end, with a warning.
# Rotation and revocation: README.md beside this script, section 5.
set -euo pipefail

out="deploy/security/generated"
days=825
ca_days=3650
ca_name="panostereo-ca"
renew=""
sensors=""
managers=""
agents=""
hosts=()
force=0

usage() { sed -n '2,24p' "$0" | sed 's/^# \{0,1\}//'; }
die() { echo "make-certs.sh: error: $*" >&2; exit 1; }

while [[ $# -gt 0 ]]; do
  case "$1" in
    --out) [[ $# -ge 2 ]] || die "--out needs a directory"; out="$2"; shift 2 ;;
    --host) [[ $# -ge 2 ]] || die "--host needs a name or address"; hosts+=("$2"); shift 2 ;;
    --sensors) [[ $# -ge 2 ]] || die "--sensors needs a list of ids"; sensors="$2"; shift 2 ;;
    --managers) [[ $# -ge 2 ]] || die "--managers needs a list of ids"; managers="$2"; shift 2 ;;
    --agents) [[ $# -ge 2 ]] || die "--agents needs a list of ids"; agents="$2"; shift 2 ;;
    --days) [[ $# -ge 2 ]] || die "--days needs a number"; days="$2"; shift 2 ;;
    --ca-days) [[ $# -ge 2 ]] || die "--ca-days needs a number"; ca_days="$2"; shift 2 ;;
    --renew) [[ $# -ge 2 ]] || die "--renew needs a list of certificate names"; renew="$2"; shift 2 ;;
    --ca-name) [[ $# -ge 2 ]] || die "--ca-name needs a name"; ca_name="$2"; shift 2 ;;
    --force) force=1; shift ;;
    -h|--help) usage; exit 0 ;;
    *) die "unknown option '$1' (expected --out, --host, --sensors, --managers, --agents, --days, --ca-days, --ca-name, --renew, --force)" ;;
  esac
done

command -v openssl >/dev/null || die "openssl is not installed (apt-get install openssl)"
[[ "$days" =~ ^[0-9]+$ && "$days" -gt 0 ]] || die "--days must be a positive integer, got '$days'"
[[ "$ca_days" =~ ^[0-9]+$ && "$ca_days" -gt 0 ]] || die "--ca-days must be a positive integer, got '$ca_days'"
id_re='^[a-z0-9][a-z0-9-]*$'
agents="$(for a in $agents; do printf '%s ' "${a%%:*}"; done)"  # make_configs.py's "ops:10" (a PTZ cap) is agent ops
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
  openssl req -new -x509 -key "$out/ca.key" -sha256 -days "$ca_days" -subj "/CN=$ca_name" \
    -addext "basicConstraints=critical,CA:TRUE" \
    -addext "keyUsage=critical,keyCertSign,cRLSign" \
    -addext "subjectKeyIdentifier=hash" \
    -out "$out/ca.pem"
  chmod 600 "$out/ca.key"
fi

# Days the CA has left: no leaf may outlive it (a client would refuse the chain then, with no warning before).
ca_end="$(openssl x509 -in "$out/ca.pem" -noout -enddate | cut -d= -f2)"
ca_left=$(( ($(date -d "$ca_end" +%s) - $(date +%s)) / 86400 ))
[[ $ca_left -gt 0 ]] || die "the CA in $out expired on $ca_end: make a new one (--force) and see README.md, rotation"
leaf_days=$days
if [[ $days -ge $ca_left ]]; then
  leaf_days=$(( ca_left > 1 ? ca_left - 1 : 1 ))
  echo "make-certs.sh: warning: --days $days would outlive the CA (ends $ca_end): new certificates end a day before it, in $leaf_days days" >&2
fi
[[ $ca_left -lt 90 ]] && echo "make-certs.sh: warning: the CA ends in $ca_left days ($ca_end): plan its rotation (README.md)" >&2

made=()
kept=()
leaf() {  # leaf NAME: NAME.key (PKCS#8) and NAME.pem signed by the CA, CN=NAME; an existing valid one is kept
  local name="$1"
  if [[ $force -eq 0 && " $renew " != *" $name "* && -s "$out/$name.pem" && -s "$out/$name.key" ]] &&
     openssl verify -CAfile "$out/ca.pem" "$out/$name.pem" >/dev/null 2>&1; then
    kept+=("$name")
    return
  fi
  made+=("$name")
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
    -CAserial "$tmp/ca.srl" -days "$leaf_days" -sha256 -extfile "$tmp/$name.ext" -out "$out/$name.pem" 2>/dev/null
  openssl verify -CAfile "$out/ca.pem" "$out/$name.pem" >/dev/null || die "certificate $name does not verify"
}

leaf router
for id in $sensors; do leaf "sensor-$id"; done
for id in $managers; do leaf "manager-$id"; done
for id in $agents; do leaf "agent-$id"; done

for name in $renew; do
  [[ "$name" =~ ^(router|(sensor|manager|agent)-[a-z0-9][a-z0-9-]*)$ ]] ||
    die "--renew takes certificate names (router, sensor-<id>, manager-<id>, agent-<id>), got '$name'"
  [[ " ${made[*]-} " == *" $name "* ]] || leaf "$name"
done
echo "make-certs.sh: in $out, CA ending $ca_end; new: ${made[*]:-none} (SAN $san, $leaf_days days); kept: ${kept[*]:-none}"
