#!/usr/bin/env bash
# The plant's public key infrastructure for ambdiag (docs/streaming.md, "Security"):
# one CA, the server's and each agent's DDS Security identity and signed
# permissions, the signed governance document, the Cyclone DDS security
# configuration of each, a CRL, and the REST service's TLS certificate.
#
#   ambdiag-pki.sh init   DIR [--days N] [--org NAME]    CA, CRL, governance, server identity
#   ambdiag-pki.sh agent  DIR PUMP_ID [--site SITE]      enrol one agent (its pump's partition SITE/PUMP_ID)
#   ambdiag-pki.sh tls    DIR HOST_OR_IP ...             the REST service's HTTPS certificate
#   ambdiag-pki.sh revoke DIR PUMP_ID                    revoke an agent's certificate (CRL), drop its folder
#
# DIR/ca/ holds the CA's private key: keep DIR/ca on the machine that enrols,
# copy only DIR/server (to the server), DIR/agents/PUMP_ID (to that agent),
# DIR/ca.pem, DIR/crl.pem and DIR/governance.p7s (to both).
# One CA signs identities, permissions and governance (see docs/streaming.md).
# Each identity folder gets security.xml, a Cyclone DDS configuration fragment
# with absolute paths; use it after the network one:
#   CYCLONEDDS_URI=file:///.../multi-host.xml,file:///DIR/server/security.xml
# The plugins' folder is found here (Debian: /usr/lib/<arch>/libddsc0debian);
# AMBDIAG_DDS_SECURITY_LIBDIR overrides it.
set -euo pipefail

die() { echo "ambdiag-pki: $*" >&2; exit 3; }
usage() { sed -n '5,9p' "$0" | sed 's/^# \{0,1\}//' >&2; exit 2; }
command -v openssl >/dev/null || die "openssl not found (deploy/install-deps.sh installs it)"

[ $# -ge 2 ] || usage
cmd=$1 dir=$2
shift 2
days=3650 org=ambdiag site=site
args=()
while [ $# -gt 0 ]; do
  case $1 in
    --days) days=${2:?--days needs a value}; shift 2 ;;
    --org) org=${2:?--org needs a value}; shift 2 ;;
    --site) site=${2:?--site needs a value}; shift 2 ;;
    --*) die "unknown option $1" ;;
    *) args+=("$1"); shift ;;
  esac
done
[[ $days =~ ^[1-9][0-9]{0,4}$ ]] || die "--days must be a whole number of days, got '$days'"
# Names end up in certificate subjects (split by Cyclone at , / |), in
# partition names (fnmatch patterns in permissions: * ? [ ]) and in paths.
plain_name() { [[ $1 =~ ^[A-Za-z0-9][A-Za-z0-9._-]{0,127}$ ]]; }
plain_name "$site" || die "--site '$site' must be 1..128 of A-Z a-z 0-9 . _ - (it is a DDS partition name)"
[[ $org =~ ^[A-Za-z0-9][A-Za-z0-9\ ._-]{0,63}$ ]] || die "--org '$org' must be letters, digits, space . _ -"

ca=$dir/ca
cnf=$ca/openssl.cnf
# openssl reads the whole configuration, the TLS section's variable included.
export AMBDIAG_PKI_SAN=${AMBDIAG_PKI_SAN:-DNS:localhost}

plugin_dir() {
  if [ -n "${AMBDIAG_DDS_SECURITY_LIBDIR:-}" ]; then
    [ -e "$AMBDIAG_DDS_SECURITY_LIBDIR/libdds_security_auth.so" ] ||
      die "AMBDIAG_DDS_SECURITY_LIBDIR=$AMBDIAG_DDS_SECURITY_LIBDIR has no libdds_security_auth.so"
    echo "$AMBDIAG_DDS_SECURITY_LIBDIR"; return
  fi
  local d
  for d in /usr/lib/*/libddsc0debian /usr/lib/*-linux-gnu /usr/local/lib /usr/lib; do
    [ -e "$d/libdds_security_auth.so" ] && { echo "$d"; return; }
  done
  die "Cyclone DDS security plugins (libdds_security_auth.so) not found; install libddsc0debian or set AMBDIAG_DDS_SECURITY_LIBDIR"
}

# Dates for the permissions' validity (UTC, the XML schema's dateTime).
# A day back: an agent whose clock lags the CA's must not start "not yet valid".
utc_days_ago() { date -u -d "-$1 days" +%Y-%m-%dT%H:%M:%S; }
utc_in_days() { date -u -d "+$1 days" +%Y-%m-%dT%H:%M:%S; }

new_key() { openssl genpkey -algorithm EC -pkeyopt ec_paramgen_curve:P-256 -out "$1" 2>/dev/null; chmod 600 "$1"; }

# S/MIME signature by the CA, as the access control plugin reads it.
sign() { openssl smime -sign -in "$1" -text -out "$2" -signer "$ca/ca.pem" -inkey "$ca/ca.key"; }

# issue KEY CERT SUBJECT EXTENSIONS: a certificate from the CA's database (for the CRL).
issue() {
  local csr=${2%.pem}.csr
  openssl req -new -key "$1" -subj "$3" -out "$csr"
  openssl ca -batch -config "$cnf" -extensions "$4" -days "$days" -notext -in "$csr" -out "$2" 2>"$csr.log" ||
    { cat "$csr.log" >&2; die "openssl ca refused to issue $2"; }
  rm -f "$csr" "$csr.log"
}

subject_of() { openssl x509 -noout -subject -nameopt RFC2253 -in "$1" | sed 's/^subject=//'; }

gen_crl() { openssl ca -config "$cnf" -gencrl -crldays "$days" -out "$dir/crl.pem" 2>/dev/null; }

# security_xml FOLDER: the Cyclone configuration fragment of one identity.
security_xml() {
  local f=$1 lib
  lib=$(plugin_dir)
  cat >"$f/security.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<!-- DDS Security for one ambdiag identity, made by deploy/security/ambdiag-pki.sh.
     Append to the network configuration:
     CYCLONEDDS_URI=file:///.../multi-host.xml,file://$f/security.xml -->
<CycloneDDS xmlns="https://cdds.io/config">
  <Domain Id="any">
    <Security>
      <Authentication>
        <Library path="$lib/libdds_security_auth.so" initFunction="init_authentication" finalizeFunction="finalize_authentication"/>
        <IdentityCA>file:$dir/ca.pem</IdentityCA>
        <IdentityCertificate>file:$f/identity.pem</IdentityCertificate>
        <PrivateKey>file:$f/identity.key</PrivateKey>
        <CRL>file:$dir/crl.pem</CRL>
      </Authentication>
      <AccessControl>
        <Library path="$lib/libdds_security_ac.so" initFunction="init_access_control" finalizeFunction="finalize_access_control"/>
        <PermissionsCA>file:$dir/ca.pem</PermissionsCA>
        <Governance>file:$dir/governance.p7s</Governance>
        <Permissions>file:$f/permissions.p7s</Permissions>
      </AccessControl>
      <Cryptographic>
        <Library path="$lib/libdds_security_crypto.so" initFunction="init_crypto" finalizeFunction="finalize_crypto"/>
      </Cryptographic>
    </Security>
  </Domain>
</CycloneDDS>
EOF
}

# permissions FOLDER GRANT_NAME PUBLISH_TOPICS PUBLISH_PARTITION SUBSCRIBE_TOPICS SUBSCRIBE_PARTITION
topic_list() { local t; for t in $1; do printf '            <topic>%s</topic>\n' "$t"; done; }
permissions() {
  local f=$1 subject
  subject=$(subject_of "$f/identity.pem")
  cat >"$f/permissions.xml" <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-Security/20170801/omg_shared_ca_permissions.xsd">
  <permissions>
    <grant name="$2">
      <subject_name>$subject</subject_name>
      <validity>
        <not_before>$(utc_days_ago 1)</not_before>
        <not_after>$(utc_in_days "$days")</not_after>
      </validity>
      <allow_rule>
        <domains><id_range><min>0</min><max>230</max></id_range></domains>
        <publish>
          <topics>
$(topic_list "$3")
          </topics>
          <partitions><partition>$4</partition></partitions>
        </publish>
        <subscribe>
          <topics>
$(topic_list "$5")
          </topics>
          <partitions><partition>$6</partition></partitions>
        </subscribe>
      </allow_rule>
      <default>DENY</default>
    </grant>
  </permissions>
</dds>
EOF
  sign "$f/permissions.xml" "$f/permissions.p7s"
}

# The topics each side writes (proto/src/stream.cc); v* keeps a later major's
# data topics (ambdiag_v2_...) allowed without new permissions.
agent_topics="ambdiag_v*_RunHeader ambdiag_v*_SampleBlock ambdiag_v*_RunEnd ambdiag_v*_MonitoringSnapshot ambdiag_AgentStatus"
server_topics="ambdiag_Ack"

governance() {
  # Every ambdiag topic: readers and writers need permissions, data encrypted,
  # submessages (heartbeats, acknacks) signed, discovery and liveliness
  # encrypted; participants without a certificate of the CA are ignored.
  cat >"$dir/governance.xml" <<'EOF'
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-Security/20170801/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>0</min><max>230</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>NONE</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>SIGN</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF
  sign "$dir/governance.xml" "$dir/governance.p7s"
}

write_ca_config() {
  cat >"$cnf" <<EOF
# The plant CA's openssl configuration (ambdiag-pki.sh).
[ ca ]
default_ca = plant
[ plant ]
dir = $ca
database = \$dir/index.txt
new_certs_dir = \$dir/issued
certificate = \$dir/ca.pem
private_key = \$dir/ca.key
serial = \$dir/serial
crlnumber = \$dir/crlnumber
default_md = sha256
policy = policy_any
unique_subject = no
[ policy_any ]
organizationName = optional
commonName = supplied
[ identity ]
basicConstraints = critical, CA:FALSE
keyUsage = critical, digitalSignature, keyAgreement
[ tls_server ]
basicConstraints = critical, CA:FALSE
keyUsage = critical, digitalSignature, keyEncipherment
extendedKeyUsage = serverAuth
subjectAltName = \${ENV::AMBDIAG_PKI_SAN}
EOF
}

case $cmd in
  init)
    [ ${#args[@]} -eq 0 ] || usage
    [ ! -e "$ca/ca.key" ] || die "$dir already has a CA ($ca/ca.key): refusing to replace it"
    mkdir -p "$ca/issued" "$dir/server" "$dir/agents"
    dir=$(cd "$dir" && pwd) ca=$dir/ca cnf=$dir/ca/openssl.cnf
    chmod 700 "$ca"
    : >"$ca/index.txt"
    echo 1000 >"$ca/serial"
    echo 1000 >"$ca/crlnumber"
    write_ca_config
    new_key "$ca/ca.key"
    openssl req -x509 -new -key "$ca/ca.key" -sha256 -days "$days" -subj "/O=$org/CN=$org plant CA" \
      -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,keyCertSign,cRLSign,digitalSignature" -out "$ca/ca.pem"
    cp "$ca/ca.pem" "$dir/ca.pem"
    gen_crl
    governance
    new_key "$dir/server/identity.key"
    issue "$dir/server/identity.key" "$dir/server/identity.pem" "/O=$org/CN=ambdiag-server" identity
    # The server reads every pump's data in every partition and acknowledges.
    permissions "$dir/server" ambdiag-server "$server_topics" "*" "$agent_topics" "*"
    security_xml "$dir/server"
    echo "ambdiag-pki: CA, CRL, governance and the server's identity in $dir" >&2
    ;;
  agent)
    [ ${#args[@]} -eq 1 ] || usage
    pump=${args[0]}
    plain_name "$pump" || die "pump id '$pump' must be 1..128 of A-Z a-z 0-9 . _ - to be enrolled (certificate subject, partition name)"
    [ -e "$ca/ca.key" ] || die "$dir has no CA: run 'ambdiag-pki.sh init $dir' first"
    dir=$(cd "$dir" && pwd) ca=$dir/ca cnf=$dir/ca/openssl.cnf
    f=$dir/agents/$pump
    [ ! -e "$f/identity.pem" ] || die "pump $pump is already enrolled ($f); revoke it first to enrol it again"
    mkdir -p "$f"
    new_key "$f/identity.key"
    issue "$f/identity.key" "$f/identity.pem" "/O=$org/CN=ambdiag-agent.$pump" identity
    # Publishes only in its own pump's partition; reads acknowledgements there.
    permissions "$f" "ambdiag-agent.$pump" "$agent_topics" "$site/$pump" "$server_topics" "$site/$pump"
    security_xml "$f"
    cat >"$f/agent.json" <<EOF
{"pump_id": "$pump", "dds": {"partition": "$site", "partition_per_pump": true}}
EOF
    echo "ambdiag-pki: agent of pump $pump enrolled in $f (partition $site/$pump)" >&2
    ;;
  tls)
    [ ${#args[@]} -ge 1 ] || usage
    [ -e "$ca/ca.key" ] || die "$dir has no CA: run 'ambdiag-pki.sh init $dir' first"
    dir=$(cd "$dir" && pwd) ca=$dir/ca cnf=$dir/ca/openssl.cnf
    san=""
    for h in "${args[@]}"; do
      if [[ $h =~ ^[0-9.]+$ || $h == *:* ]]; then san+="${san:+,}IP:$h"; else san+="${san:+,}DNS:$h"; fi
    done
    mkdir -p "$dir/tls"
    new_key "$dir/tls/server.key"
    AMBDIAG_PKI_SAN=$san issue "$dir/tls/server.key" "$dir/tls/server.pem" "/O=$org/CN=${args[0]}" tls_server
    echo "ambdiag-pki: HTTPS certificate for ${args[*]} in $dir/tls (server.pem, server.key)" >&2
    ;;
  revoke)
    [ ${#args[@]} -eq 1 ] || usage
    pump=${args[0]}
    dir=$(cd "$dir" && pwd) ca=$dir/ca cnf=$dir/ca/openssl.cnf
    f=$dir/agents/$pump
    [ -e "$f/identity.pem" ] || die "pump $pump is not enrolled in $dir"
    openssl ca -config "$cnf" -revoke "$f/identity.pem" 2>/dev/null || die "openssl ca could not revoke $f/identity.pem"
    gen_crl
    rm -rf "$f"
    echo "ambdiag-pki: pump $pump revoked; copy $dir/crl.pem to the server and restart it" >&2
    ;;
  *) usage ;;
esac
