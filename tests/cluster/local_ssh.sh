#!/bin/sh
# A stand-in for ssh that runs the remote command on this machine, so that GNU parallel's
# multi-host path (--sshloginfile, the command sent through a remote shell) is exercised on one
# CI machine: `parallel --ssh tests/cluster/local_ssh.sh --sshloginfile HOSTS`, HOSTS naming
# made-up hosts. parallel calls it as `local_ssh.sh [ssh options] HOST -- COMMAND`.
while [ $# -gt 0 ]; do
  case "$1" in
    --) shift; break ;;
    *) shift ;;
  esac
done
exec /bin/sh -c "$*"
