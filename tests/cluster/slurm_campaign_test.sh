#!/usr/bin/env bash
# A campaign on a real Slurm (issue 22, item 2): a one-node cluster on this machine from
# Debian's slurm-wlm and munge (bin/setup installs them), in a network namespace of the test's
# own that holds only a loopback interface and a veth pair with both ends inside it
# (SlurmctldHost=localhost), so nothing it sends can leave the machine. bin/campaign-slurm submits the campaign as a job array of shards and a
# merge job that depends on it; the merged campaign.csv and summary.md must equal the
# unsharded run's byte for byte. Then a shard is killed (cancelled before it runs): the merge
# must fail naming it. Skips (exit 77, with the reason) only where the daemons cannot start.
#   slurm_campaign_test.sh SOURCE_DIR BUILD_DIR
set -u
src="$1"; build="$2"
source "$src/tests/cli/lib.sh"
skip() { echo "SKIP: $*"; exit 77; }
for t in munged slurmctld slurmd sbatch squeue scancel scontrol; do
  command -v "$t" >/dev/null || fail "$t not installed (bin/setup installs slurm-wlm and munge)"
done
tmp=$(mktemp -d /tmp/cell_slurm.XXXXXX)
chmod 755 "$tmp"
ns="cellslurm$$"
in_ns=()
cleanup() {
  for p in slurmd slurmctld munged; do
    [ -f "$tmp/$p.pid" ] && kill "$(cat "$tmp/$p.pid")" 2>/dev/null
  done
  sleep 1
  for p in slurmd slurmctld munged; do
    [ -f "$tmp/$p.pid" ] && kill -KILL "$(cat "$tmp/$p.pid")" 2>/dev/null
  done
  [ ${#in_ns[@]} -gt 0 ] && ip netns del "$ns" 2>/dev/null
  rm -rf "$tmp"
}
trap cleanup EXIT
# KEEP_SLURM=1: leave the cluster running and its folder in place, to look into a failure
[ -n "${KEEP_SLURM:-}" ] && trap - EXIT

# the cluster's own network: a namespace with loopback only (or, where namespaces cannot be
# made, this machine's loopback, which the daemons are told to use)
# Slurm asks getaddrinfo for AI_ADDRCONFIG addresses, which a namespace of loopback alone has
# none of: a veth pair with both ends inside the namespace gives it one that leads nowhere
if ip netns add "$ns" 2>/dev/null && ip netns exec "$ns" sh -c 'ip link set lo up &&
     ip link add cell_a type veth peer name cell_b && ip addr add 169.254.77.1/32 dev cell_a &&
     ip link set cell_a up && ip link set cell_b up' 2>/dev/null; then
  # nsenter, not `ip netns exec`: that mounts a sysfs of its own, without /sys/fs/cgroup, and
  # slurmd will not start without it
  in_ns=(nsenter --net="/run/netns/$ns")
  where="network namespace $ns (loopback and a veth pair inside it only)"
else
  ip netns del "$ns" 2>/dev/null
  where="this machine's loopback (no network namespace could be made)"
fi
run() { "${in_ns[@]}" "$@"; }

mkdir -p "$tmp/state" "$tmp/spool" "$tmp/log"
head -c 1024 /dev/urandom >"$tmp/munge.key"; chmod 400 "$tmp/munge.key"
run munged --force --key-file="$tmp/munge.key" --socket="$tmp/munge.sock" --pid-file="$tmp/munged.pid" \
  --seed-file="$tmp/munged.seed" --log-file="$tmp/log/munged.log" 2>"$tmp/log/munged.err" ||
  skip "munged does not start here: $(tail -1 "$tmp/log/munged.err")"
port=$(( 17000 + ($$ % 500) * 2 ))
# on this machine's loopback, slurmd binds 127.0.0.1 only; in the namespace there is nothing
# else to bind (and NoInAddrAny would look up the machine's hostname, not there)
comm=""; [ ${#in_ns[@]} -eq 0 ] && comm="CommunicationParameters=NoInAddrAny"
cat >"$tmp/slurm.conf" <<EOF
ClusterName=cellci
SlurmctldHost=localhost(127.0.0.1)
SlurmctldPort=$port
SlurmdPort=$((port + 1))
$comm
SlurmUser=root
SlurmdUser=root
AuthType=auth/munge
AuthInfo=socket=$tmp/munge.sock
CredType=cred/munge
StateSaveLocation=$tmp/state
SlurmdSpoolDir=$tmp/spool
SlurmctldPidFile=$tmp/slurmctld.pid
SlurmdPidFile=$tmp/slurmd.pid
SlurmctldLogFile=$tmp/log/slurmctld.log
SlurmdLogFile=$tmp/log/slurmd.log
ProctrackType=proctrack/linuxproc
TaskPlugin=task/none
SelectType=select/cons_tres
SelectTypeParameters=CR_Core
SchedulerType=sched/backfill
JobAcctGatherType=jobacct_gather/none
AccountingStorageType=accounting_storage/none
JobCompType=jobcomp/none
MpiDefault=none
ReturnToService=2
InactiveLimit=0
KillWait=5
NodeName=localhost NodeAddr=127.0.0.1 CPUs=2 State=UNKNOWN
PartitionName=cell Nodes=localhost Default=YES MaxTime=INFINITE State=UP
EOF
export SLURM_CONF="$tmp/slurm.conf"
run slurmctld -f "$SLURM_CONF" -i 2>"$tmp/log/slurmctld.err" || skip "slurmctld does not start here: $(tail -1 "$tmp/log/slurmctld.err")"
run slurmd -f "$SLURM_CONF" -N localhost 2>"$tmp/log/slurmd.err" || skip "slurmd does not start here: $(tail -1 "$tmp/log/slurmd.err")"
# the node idle: bounded at 60 s (each query bounded too: a client waits for a dead controller)
idle() { [ "$(run timeout 10 sinfo -h -o %T 2>/dev/null)" = "idle" ]; }
until idle || [ $SECONDS -gt 60 ]; do sleep 0.2; done
idle ||
  skip "the one-node cluster did not come up in 60 s: $(tail -2 "$tmp/log/slurmctld.log" "$tmp/log/slurmd.log" 2>/dev/null | tr '\n' ' ')"
echo "slurm: a one-node cluster in $where: $(run sinfo -h -o '%P %a %D %T %N')"

args=("$src/sim/scenarios/fig5.yaml" --features ideal --runs 6 --models desired,current --max-iterations 80)
"$build/bin/cellsim" campaign "${args[@]}" --threads 2 --no-plot -o "$tmp/whole" >/dev/null 2>&1 || fail "the unsharded campaign"

# three shards as a job array, then the merge (sbatch --wait: bounded by the test's timeout)
out=$(BUILD_DIR="$build" run timeout 240 "$src/bin/campaign-slurm" --shards 3 -o "$tmp/slurm" --wait -- "${args[@]}" 2>&1) ||
  fail "bin/campaign-slurm: $out; merge log: $(cat "$tmp/slurm/merge.log" 2>/dev/null)"
echo "$out"
for i in 1 2 3; do [ -s "$tmp/slurm/shard_$i/campaign.csv" ] || fail "shard $i wrote nothing: $(cat "$tmp/slurm/shard_$i.log")"; done
cmp -s "$tmp/whole/campaign.csv" "$tmp/slurm/all/campaign.csv" || fail "the merged campaign.csv differs from the unsharded one"
cmp -s "$tmp/whole/summary.md" "$tmp/slurm/all/summary.md" || fail "the merged summary.md differs from the unsharded one"
echo "slurm: 3 shards as a job array and a dependent merge: campaign.csv and summary.md equal the unsharded run's"

# ordinary paths that sbatch's #SBATCH lines could not hold (issue 40, item 8): a space, '$', a
# backtick and a '#' run and merge; a file at the path before the '#' is left as it was; '%'
# (a Slurm replacement symbol) is refused before anything is made
odd="$tmp/odd dir \$HOME \`x\` a#b"
printf 'keep\n%.0s' {1..1000} >"$tmp/odd dir \$HOME \`x\` a"
out=$(BUILD_DIR="$build" run timeout 240 "$src/bin/campaign-slurm" --shards 2 -o "$odd" --wait -- "${args[@]}" 2>&1) ||
  fail "bin/campaign-slurm under '$odd': $out; merge log: $(cat "$odd/merge.log" 2>/dev/null)"
cmp -s "$tmp/whole/campaign.csv" "$odd/all/campaign.csv" || fail "the merged campaign under '$odd' differs"
[ -s "$odd/shard_1.log" ] && [ -s "$odd/shard_2.log" ] && [ -s "$odd/merge.log" ] || fail "no logs under '$odd': $(ls "$odd")"
[ "$(wc -l <"$tmp/odd dir \$HOME \`x\` a")" -eq 1000 ] || fail "the file before the '#' was written to"
err=$(BUILD_DIR="$build" run "$src/bin/campaign-slurm" --shards 2 -o "$tmp/pct%jdir" -- "${args[@]}" 2>&1) &&
  fail "a path with '%' was submitted: $err"
[ -e "$tmp/pct%jdir" ] && fail "a refused path was made: $err"
grep -q "'%'" <<<"$err" || fail "the refusal of '%' does not say why: $err"
echo "slurm: a space, \$, a backtick and a '#' in the output path run and merge; '%' is refused before anything is made"

# a shard killed: the array held, task 2 cancelled, the rest released; the merge names shard 2
out=$(BUILD_DIR="$build" run "$src/bin/campaign-slurm" --shards 3 -o "$tmp/killed" --hold -- "${args[@]}" 2>&1) ||
  fail "bin/campaign-slurm --hold: $out"
array=$(sed -n 's/^campaign-slurm: shards: job array \([0-9]*\) .*/\1/p' <<<"$out")
merge=$(sed -n 's/^campaign-slurm: merge: job \([0-9]*\) .*/\1/p' <<<"$out")
[ -n "$array" ] && [ -n "$merge" ] || fail "no job ids in: $out"
run scancel "${array}_2" || fail "scancel ${array}_2"
run scontrol release "$array" || fail "scontrol release $array"
# the merge job ends (bounded at 240 s)
ended() { [ -z "$(run timeout 10 squeue -h -j "$merge" 2>/dev/null)" ] && [ -f "$tmp/killed/merge.log" ]; }
limit=$((SECONDS + 240))
until ended || [ $SECONDS -gt $limit ]; do sleep 0.2; done
ended || fail "the merge job $merge did not end in 240 s"
log=$(cat "$tmp/killed/merge.log" 2>/dev/null)
grep -q "shard_2: shard missing" <<<"$log" || fail "the merge did not name the killed shard: $log"
grep -q "missing: shard 2/3" <<<"$log" || fail "campaign merge did not name shard 2/3: $log"
[ -e "$tmp/killed/all/campaign.csv" ] && fail "a campaign with a shard missing was merged"
echo "slurm: a killed shard is named by the merge, which writes nothing: $(grep 'missing: shard' <<<"$log")"
