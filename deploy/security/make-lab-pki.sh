#!/usr/bin/env bash
# Makes a godhand lab's DDS-Security PKI with openssl: a CA, one identity (key + certificate) per
# name given, and the CA-signed governance and permissions documents (S/MIME, what Fast DDS's
# builtin Access-Permissions plugin reads).
#
# usage: make-lab-pki.sh OUTDIR NAME:ROLE [NAME:ROLE ...]
#   NAME  an identity: a host ("scene-pc") or a service; its certificate's subject is
#         CN=NAME,O=godhand-lab
#   ROLE  what that identity may publish (every identity may subscribe to every godhand topic):
#           ingest     HandTarget                         (the tracker host / godhand-ingest)
#           solver     HandProposal                       (the solver host / godhand-solver)
#           scene      HandState, ContactForces, SceneState, SceneDescription, SceneResume
#                      (the host of godhand-scene and godhand-resolver, or either of them)
#           resolver   HandState, ContactForces, SceneResume (the scene state held for a restarted scene)
#           monitor    nothing (only ServiceStatus, like every role): godhand-launch's monitor
#                      on a host without services, a renderer
#         every role publishes ServiceStatus (heartbeats).
# Writes OUTDIR/ca.key, ca.pem, NAME.key, NAME.pem, governance.xml/.p7s, permissions.xml/.p7s.
# Options (environment): GODHAND_PKI_DAYS (validity, default 365), GODHAND_PKI_DOMAINS
# (domain range of the rules, default 0-232), GODHAND_PKI_RTPS_PROTECTION (whole RTPS messages:
# ENCRYPT, the default, SIGN or NONE; submessages and data stay encrypted either way).
#
# Governance: no unauthenticated participant may join (allow_unauthenticated_participants
# false), join and topic access control on, discovery, liveliness and RTPS messages encrypted
# and every topic's data and metadata encrypted (AES-GCM-GMAC). Keys never leave OUTDIR: keep it
# private (chmod 700), copy to each host only its own key. Generate, never commit.
set -euo pipefail

usage() { sed -n '2,/^set -euo/p' "$0" | grep '^#' | sed 's/^# \{0,1\}//'; }
if [[ "${1:-}" == "-h" || "${1:-}" == "--help" ]]; then
  usage
  exit 0
fi
if [[ $# -lt 2 ]]; then
  echo "make-lab-pki.sh: expected OUTDIR NAME:ROLE [NAME:ROLE ...] (see --help)" >&2
  exit 2
fi
command -v openssl >/dev/null || { echo "make-lab-pki.sh: openssl not found (apt-get install openssl)" >&2; exit 2; }
out=$1
shift
days=${GODHAND_PKI_DAYS:-365}
domains=${GODHAND_PKI_DOMAINS:-0-232}
dmin=${domains%-*}
dmax=${domains#*-}
[[ "$days" =~ ^[0-9]+$ && "$dmin" =~ ^[0-9]+$ && "$dmax" =~ ^[0-9]+$ ]] ||
  { echo "make-lab-pki.sh: GODHAND_PKI_DAYS must be a number, GODHAND_PKI_DOMAINS MIN-MAX" >&2; exit 2; }
rtps=${GODHAND_PKI_RTPS_PROTECTION:-ENCRYPT}
case $rtps in ENCRYPT | SIGN | NONE) ;;
  *) echo "make-lab-pki.sh: GODHAND_PKI_RTPS_PROTECTION must be ENCRYPT, SIGN or NONE, got '$rtps'" >&2; exit 2 ;;
esac

declare -a names roles
for spec in "$@"; do
  name=${spec%%:*}
  role=${spec#*:}
  [[ "$spec" == *:* && "$name" =~ ^[A-Za-z0-9._-]{1,63}$ ]] ||
    { echo "make-lab-pki.sh: bad identity '$spec' (expected NAME:ROLE, NAME of A-Z a-z 0-9 . _ -)" >&2; exit 2; }
  case $role in ingest | solver | scene | resolver | monitor) ;;
    *) echo "make-lab-pki.sh: $name: unknown role '$role' (ingest, solver, scene, resolver, monitor)" >&2; exit 2 ;;
  esac
  names+=("$name")
  roles+=("$role")
done

mkdir -p "$out"
chmod 700 "$out"
cd "$out"
umask 077
quiet() { "$@" >/dev/null 2>openssl.err || { cat openssl.err >&2; exit 1; }; }

# CA (identity CA and permissions CA in one): ECDSA P-256, self-signed.
quiet openssl ecparam -name prime256v1 -genkey -noout -out ca.key
quiet openssl req -x509 -new -key ca.key -sha256 -days "$days" -subj "/O=godhand-lab/CN=godhand-lab CA" -out ca.pem \
  -addext "basicConstraints=critical,CA:TRUE" -addext "keyUsage=critical,digitalSignature,keyCertSign,cRLSign"

# One identity per name.
for name in "${names[@]}"; do
  quiet openssl ecparam -name prime256v1 -genkey -noout -out "$name.key"
  quiet openssl req -new -key "$name.key" -sha256 -subj "/O=godhand-lab/CN=$name" -out "$name.csr"
  printf 'basicConstraints=CA:FALSE\nkeyUsage=critical,digitalSignature,keyAgreement\n' >ext.cnf
  quiet openssl x509 -req -in "$name.csr" -CA ca.pem -CAkey ca.key -CAcreateserial -days "$days" -sha256 \
    -extfile ext.cnf -out "$name.pem"
  rm -f "$name.csr" ext.cnf
done
rm -f ca.srl openssl.err

cat >governance.xml <<EOF
<?xml version="1.0" encoding="UTF-8"?>
<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"
     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_governance.xsd">
  <domain_access_rules>
    <domain_rule>
      <domains><id_range><min>$dmin</min><max>$dmax</max></id_range></domains>
      <allow_unauthenticated_participants>false</allow_unauthenticated_participants>
      <enable_join_access_control>true</enable_join_access_control>
      <discovery_protection_kind>ENCRYPT</discovery_protection_kind>
      <liveliness_protection_kind>ENCRYPT</liveliness_protection_kind>
      <rtps_protection_kind>$rtps</rtps_protection_kind>
      <topic_access_rules>
        <topic_rule>
          <topic_expression>*</topic_expression>
          <enable_discovery_protection>true</enable_discovery_protection>
          <enable_liveliness_protection>true</enable_liveliness_protection>
          <enable_read_access_control>true</enable_read_access_control>
          <enable_write_access_control>true</enable_write_access_control>
          <metadata_protection_kind>ENCRYPT</metadata_protection_kind>
          <data_protection_kind>ENCRYPT</data_protection_kind>
        </topic_rule>
      </topic_access_rules>
    </domain_rule>
  </domain_access_rules>
</dds>
EOF

publishes() {
  case $1 in
    ingest) echo "godhand/hand_target" ;;
    solver) echo "godhand/hand_proposal" ;;
    scene) echo "godhand/hand_state godhand/contact_forces godhand/scene_state godhand/scene_description godhand/scene_resume" ;;
    resolver) echo "godhand/hand_state godhand/contact_forces godhand/scene_resume" ;;
    monitor) echo "" ;;
  esac
}
not_before=$(date -u +%Y-%m-%dT%H:%M:%S)
not_after=$(date -u -d "+$days days" +%Y-%m-%dT%H:%M:%S)
{
  echo '<?xml version="1.0" encoding="UTF-8"?>'
  echo '<dds xmlns:xsi="http://www.w3.org/2001/XMLSchema-instance"'
  echo '     xsi:noNamespaceSchemaLocation="http://www.omg.org/spec/DDS-SECURITY/20170901/omg_shared_ca_permissions.xsd">'
  echo '  <permissions>'
  for i in "${!names[@]}"; do
    echo "    <grant name=\"${names[$i]}\">"
    echo "      <subject_name>CN=${names[$i]},O=godhand-lab</subject_name>"
    echo "      <validity><not_before>$not_before</not_before><not_after>$not_after</not_after></validity>"
    echo "      <allow_rule>"
    echo "        <domains><id_range><min>$dmin</min><max>$dmax</max></id_range></domains>"
    echo "        <publish><topics>"
    for t in godhand/service_status $(publishes "${roles[$i]}"); do echo "          <topic>$t</topic>"; done
    echo "        </topics></publish>"
    echo "        <subscribe><topics><topic>godhand/*</topic></topics></subscribe>"
    echo "      </allow_rule>"
    echo "      <default>DENY</default>"
    echo "    </grant>"
  done
  echo '  </permissions>'
  echo '</dds>'
} >permissions.xml

for doc in governance permissions; do
  openssl smime -sign -in "$doc.xml" -text -out "$doc.p7s" -signer ca.pem -inkey ca.key 2>/dev/null ||
    { echo "make-lab-pki.sh: signing $doc.xml failed" >&2; exit 1; }
done
chmod 600 ./*.key
chmod 644 ca.pem ./*.p7s ./*.xml
for name in "${names[@]}"; do chmod 644 "$name.pem"; done
echo "make-lab-pki.sh: CA, ${#names[@]} identities (${names[*]}), signed governance and permissions in $(pwd)"
