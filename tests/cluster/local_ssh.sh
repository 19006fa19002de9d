#!/bin/sh
# A stand-in for ssh that runs the remote command on this machine, so that GNU parallel's
# multi-host path (--sshloginfile, the command sent through a remote shell) is exercised on one
# CI machine: `parallel --ssh tests/cluster/local_ssh.sh --sshloginfile HOSTS`, HOSTS naming
# made-up hosts. parallel calls it as `local_ssh.sh [ssh options] HOST -- COMMAND`.
# Like sshd, it sets SHELL to the user's login shell: parallel's remote worker runs each job with
# $SHELL, and with SHELL unset (as in some CI runners) it silently runs nothing.
while [ $# -gt 0 ]; do
  case "$1" in
    --) shift; break ;;
    *) shift ;;
  esac
done
login_shell=$(getent passwd "$(id -u)" | cut -d: -f7)
SHELL=${login_shell:-/bin/sh}
export SHELL
exec /bin/sh -c "$*"
