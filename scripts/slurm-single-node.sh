#!/usr/bin/env bash
# Starts a single-node Slurm cluster on this machine (as root): munged, slurmctld and slurmd with
# a minimal slurm.conf (one partition "areomap" holding this host with all its cores), then waits
# until the node is idle. For CI and for trying `areomap run --executor slurm` on one machine;
# a real cluster has its own configuration. Needs Debian's slurm-wlm and munge
# (scripts/install-deps.sh --cluster). Exits non-zero, with the daemons' logs, if the node does
# not come up within 60 s.
set -euo pipefail
if [ "$(id -u)" != 0 ]; then
  command -v sudo >/dev/null && exec sudo bash "$0" "$@"
  echo "slurm-single-node.sh: run as root (it writes /etc/slurm and starts daemons)" >&2
  exit 2
fi
if sinfo --noheader --format=%T 2>/dev/null | grep -qE "idle|mix|alloc"; then
  echo "slurm: already running"
  sinfo
  exit 0
fi
host=$(hostname -s)
cpus=$(nproc)
memory_mb=$(awk '/MemTotal/ {print int($2 / 1024) - 512}' /proc/meminfo)
mkdir -p /etc/slurm /var/spool/slurmctld /var/spool/slurmd /var/log/slurm /run/munge
cat > /etc/slurm/slurm.conf <<CONF
# Written by areomap's scripts/slurm-single-node.sh: one node, no accounting, no cgroups.
ClusterName=areomap
SlurmctldHost=${host}
SlurmUser=root
AuthType=auth/munge
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
StateSaveLocation=/var/spool/slurmctld
SlurmdSpoolDir=/var/spool/slurmd
SlurmctldLogFile=/var/log/slurm/slurmctld.log
SlurmdLogFile=/var/log/slurm/slurmd.log
ReturnToService=2
MpiDefault=none
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
NodeName=${host} CPUs=${cpus} RealMemory=${memory_mb} State=UNKNOWN
PartitionName=areomap Nodes=${host} Default=YES MaxTime=INFINITE State=UP
CONF
[ -f /etc/munge/munge.key ] || mungekey --create
chown munge:munge /etc/munge/munge.key /run/munge 2>/dev/null || true
pgrep -x munged >/dev/null || su -s /bin/sh munge -c /usr/sbin/munged || /usr/sbin/munged --force
pgrep -x slurmctld >/dev/null || slurmctld
pgrep -x slurmd >/dev/null || slurmd
for _ in $(seq 1 60); do
  if sinfo --noheader --format=%T 2>/dev/null | grep -qE "idle|mix|alloc"; then
    sinfo
    exit 0
  fi
  sleep 1
done
echo "slurm-single-node.sh: the node did not come up; the daemons' logs:" >&2
tail -n 30 /var/log/slurm/slurmctld.log /var/log/slurm/slurmd.log >&2 || true
exit 1
