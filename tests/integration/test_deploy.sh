#!/usr/bin/env bash
# test_deploy.sh: checks the deploy/ recipes as far as one machine without a
# cluster allows (docs/cluster.md, "How these recipes are checked"):
#
#  1. shellcheck on every shell script in deploy/;
#  2. systemd-analyze verify on both units (ExecStart pointed at the build,
#     the template as an instance); a warning fails; a known-bad unit must
#     be caught first, so a verify that checks nothing cannot pass; the
#     offline security rating of each unit;
#  3. yamllint on the Kubernetes manifests, then a structural check of them
#     (selectors and labels, Secret names and keys, ports, the workers'
#     endpoint, non-root security contexts);
#  4. make-secret.sh: its Secrets carry working keys (a CURVE render on
#     loopback with exactly those files), and the workers' Secret holds no
#     coordinator secret;
#  5. the Slurm script end to end with stand-in srun and scontrol (two
#     "nodes", both this machine): image in the submit directory,
#     bit-identical to the in-process render, key directory removed;
#  6. the Containerfile: every source folder the build needs is copied, and
#     its runtime packages are what install-deps.sh's -dev packages depend
#     on; hadolint when installed;
#  7. install.sh's options, and `cmake --install` into a temporary prefix when
#     the build has the install rules (cmake/install.cmake).
#
# A check whose tool is missing prints "SKIP: ..." with the Debian package
# that provides it. yamllint is installed (apt-get) when missing and this
# runs as root. Renders are tiny and bound to loopback; every wait is bounded.
#
# usage: tests/integration/test_deploy.sh [photonfarm [photonfarm-worker [build dir]]]
set -u

ROOT=$(cd "$(dirname "$0")/../.." && pwd)
abs() { case $1 in /*) echo "$1" ;; *) echo "$PWD/$1" ;; esac; }
PF=$(abs "${1:-$ROOT/build/bin/photonfarm}")
PFW=$(abs "${2:-$ROOT/build/bin/photonfarm-worker}")
BUILD=$(abs "${3:-$ROOT/build}")
cd "$ROOT" || exit 1

T=$(mktemp -d "${TMPDIR:-/tmp}/pf_deploy.XXXXXX") || exit 1
PIDS=()
cleanup() {
    local p
    for p in "${PIDS[@]}"; do
        kill -9 "$p" 2>/dev/null
    done
    wait 2>/dev/null
    rm -rf "$T"
}
trap cleanup EXIT
trap 'exit 130' INT TERM

# shellcheck source=tests/integration/lib.sh
. "$(dirname "$0")/lib.sh"
have() { command -v "$1" >/dev/null 2>&1; }
has() { grep -qE -- "$2" "$1" 2>/dev/null; }
hasnt() { ! grep -qE -- "$2" "$1" 2>/dev/null; }
eq() { [ "$1" = "$2" ]; }
gt() { [ "$1" -gt "$2" ]; }
free_port() {
    python3 -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])'
}
# quiet_ok CMD...: true when CMD exits 0 and prints nothing on stderr
# (its stderr is kept in $T/last.err).
quiet_ok() {
    "$@" 2>"$T/last.err" >/dev/null && [ ! -s "$T/last.err" ]
}

TINY=(--size 64x64 --spp 1 --photons 20000 --caustic-photons 20000 --gather 4 --tile 16)
SPHERES=scenes/cornell-spheres/scene.json
exes_ok=1
for exe in "$PF" "$PFW"; do
    [ -x "$exe" ] || {
        bad "$exe is an executable (the checks that render are skipped)"
        exes_ok=0
    }
done

# ---- 1. shellcheck ------------------------------------------------------------

echo "# 1. shellcheck"
scripts=()
while IFS= read -r f; do
    if head -n 1 "$f" | grep -qE '^#!.*\b(ba)?sh\b'; then
        scripts+=("$f")
    fi
done < <(find deploy -type f | sort)
if have shellcheck; then
    for f in "${scripts[@]}"; do
        if shellcheck -x "$f" >"$T/sc.out" 2>&1; then
            ok "shellcheck $f"
        else
            bad "shellcheck $f"
            show "$T/sc.out" 20
        fi
    done
    check "shellcheck found the scripts (${#scripts[@]}, the Slurm script among them)" \
        has <(printf '%s\n' "${scripts[@]}") 'photonfarm\.sbatch'
else
    skip "shellcheck not installed (Debian package shellcheck): ${#scripts[@]} scripts in deploy/ not linted"
fi

# ---- 2. systemd units -------------------------------------------------------------

echo "# 2. systemd units"
UNITS=deploy/systemd
# unit_copy NAME [AS]: the unit with ExecStart pointed at the build's
# executables (verify insists that the program exists), in $T/units/AS.
unit_copy() {
    mkdir -p "$T/units"
    sed -e "s|/usr/local/bin/photonfarm-worker|$PFW|" -e "s|/usr/local/bin/photonfarm|$PF|" \
        "$UNITS/$1" >"$T/units/${2:-$1}"
}
if ! have systemd-analyze; then
    skip "systemd-analyze not installed (Debian package systemd): the units are not verified"
elif [ "$exes_ok" = 0 ]; then
    skip "the units are not verified without the executables"
else
    mkdir -p "$T/units"
    printf '[Unit]\nDescription=calibration\n[Service]\nType=exec\nExecStart=%s --version\n' "$PF" \
        >"$T/units/pf-good.service"
    printf '[Unit]\nDescription=calibration\n[Service]\nType=exec\nExecStart=%s --version\nRestart=sometimes\nNoSuchSetting=1\n' \
        "$PF" >"$T/units/pf-bad.service"
    if ! (cd "$T/units" && quiet_ok systemd-analyze verify ./pf-good.service); then
        skip "systemd-analyze verify does not work here ($(head -n 1 "$T/last.err")): the units are not verified"
    else
        (cd "$T/units" && systemd-analyze verify ./pf-bad.service >/dev/null 2>"$T/bad.err")
        check "systemd-analyze verify reports a broken unit here (so a clean verify means something)" \
            has "$T/bad.err" 'NoSuchSetting|Unknown key'
        unit_copy photonfarm-worker.service
        unit_copy photonfarm-coordinator@.service photonfarm-coordinator@test.service
        for u in photonfarm-worker.service photonfarm-coordinator@test.service; do
            if (cd "$T/units" && quiet_ok systemd-analyze verify "./$u"); then
                ok "systemd-analyze verify $u: no error, no warning"
            else
                bad "systemd-analyze verify $u"
                show "$T/last.err"
            fi
        done
        for u in photonfarm-worker.service photonfarm-coordinator@test.service; do
            (cd "$T/units" && systemd-analyze security --offline=yes "./$u" >"$T/sec.out" 2>&1)
            level=$(grep -oE 'Overall exposure level for [^:]+: [0-9.]+' "$T/sec.out" | grep -oE '[0-9.]+$')
            if [ -z "$level" ]; then
                skip "systemd-analyze security --offline is not supported here (systemd 250 or later)"
                break
            fi
            # Below 2.0 is "OK" on systemd's scale; a lost hardening line
            # (ProtectSystem, the system-call filter, ...) pushes it above.
            check "$u: exposure $level of 10 (<= 2.0, systemd-analyze security)" \
                awk -v l="$level" 'BEGIN { exit !(l <= 2.0) }'
        done
        # A refused worker no longer exits (it retries by itself, backoff up
        # to 300 s), so only a usage error (2) is kept from restarting, and
        # the unit must not make it a one-job worker (--exit-on-bye exits).
        check "the worker unit restarts on failure only, not on usage errors (a refusal does not end it)" \
            has "$UNITS/photonfarm-worker.service" '^Restart=on-failure$' &&
            has "$UNITS/photonfarm-worker.service" '^RestartPreventExitStatus=2$' &&
            hasnt "$UNITS/photonfarm-worker.service" '^ExecStart=.*exit-on-bye'
        for u in photonfarm-worker.service photonfarm-coordinator@.service; do
            for k in 'NoNewPrivileges=yes' 'ProtectSystem=strict' 'ProtectHome=yes' 'PrivateTmp=yes' \
                'RestrictAddressFamilies=AF_INET AF_INET6 AF_UNIX' 'User=photonfarm' 'EnvironmentFile='; do
                has "$UNITS/$u" "^$k" || bad "$u has $k"
            done
        done
        ok "both units carry the hardening lines, the unprivileged user and an EnvironmentFile"
        # The env examples name every variable the units use.
        for pair in photonfarm-worker.service:worker.env.example photonfarm-coordinator@.service:coordinator.env.example; do
            u=${pair%%:*}
            e=${pair#*:}
            missing=""
            while read -r v; do
                has "$UNITS/$e" "^$v=" || missing="$missing $v"
            done < <(grep -oE '[$][{]?PF_[A-Z_]+' "$UNITS/$u" | sed 's/^[$][{]\{0,1\}//' | sort -u)
            check "$e sets every variable $u uses${missing:+ (missing:$missing)}" eq "$missing" ""
        done
    fi
fi

# ---- 3. Kubernetes manifests -------------------------------------------------------

echo "# 3. Kubernetes manifests"
K8S=deploy/k8s
if ! have yamllint && [ "$(id -u)" -eq 0 ] && have apt-get; then
    note "yamllint missing: installing it (apt-get install yamllint)"
    export DEBIAN_FRONTEND=noninteractive
    if ! timeout 300 apt-get install -y -q yamllint >"$T/apt.log" 2>&1; then
        timeout 300 apt-get update -q >>"$T/apt.log" 2>&1
        timeout 300 apt-get install -y -q yamllint >>"$T/apt.log" 2>&1
    fi
fi
if have yamllint; then
    for f in "$K8S"/*.yaml; do
        if yamllint -s -c "$K8S/.yamllint" "$f" >"$T/yl.out" 2>&1; then
            ok "yamllint $f"
        else
            bad "yamllint $f"
            show "$T/yl.out"
        fi
    done
else
    skip "yamllint not installed and could not be installed (Debian package yamllint): the manifests are not linted"
fi

if python3 -c 'import yaml' 2>/dev/null; then
    if python3 - "$K8S" >"$T/k8s.out" 2>&1 <<'EOF'; then
import os, re, sys, yaml

k8s = sys.argv[1]
problems = []
docs = {}
for name in sorted(os.listdir(k8s)):
    if not name.endswith(".yaml") or name == "kustomization.yaml":
        continue
    for d in yaml.safe_load_all(open(os.path.join(k8s, name))):
        if d is None:
            continue
        for field in ("apiVersion", "kind"):
            if field not in d:
                problems.append(f"{name}: no {field}")
        md = d.get("metadata", {})
        if not md.get("name"):
            problems.append(f"{name}: no metadata.name")
        docs[(d.get("kind"), md.get("name"))] = (name, d)

def get(kind, name):
    if (kind, name) not in docs:
        problems.append(f"no {kind} named {name}")
        return None
    return docs[(kind, name)][1]

kust = yaml.safe_load(open(os.path.join(k8s, "kustomization.yaml")))
for r in kust.get("resources", []):
    if not os.path.exists(os.path.join(k8s, r)):
        problems.append(f"kustomization.yaml lists {r}, which does not exist")
listed = set(kust.get("resources", []))
for (kind, name), (f, _) in docs.items():
    if kind != "Secret" and f not in listed:
        problems.append(f"{f} ({kind} {name}) is not in kustomization.yaml")
    if kind == "Secret" and f in listed:
        problems.append(f"{f}: a Secret template must not be applied by kustomize")

svc = get("Service", "photonfarm-coordinator")
dep = get("Deployment", "photonfarm-worker")
job = get("Job", "photonfarm-render")
secrets = {n: d for (k, n), (_, d) in docs.items() if k == "Secret"}

def pod_labels(obj):
    return obj["spec"]["template"]["metadata"]["labels"]

def matches(selector, labels):
    return all(labels.get(k) == v for k, v in selector.items())

if svc and job:
    if not matches(svc["spec"]["selector"], pod_labels(job)):
        problems.append("the Service does not select the coordinator Job's pod")
    if dep and matches(svc["spec"]["selector"], pod_labels(dep)):
        problems.append("the Service also selects the worker pods")
    ports = {p.get("name"): p["containerPort"]
             for c in job["spec"]["template"]["spec"]["containers"] for p in c.get("ports", [])}
    for p in svc["spec"]["ports"]:
        if p["targetPort"] not in ports and p["targetPort"] not in ports.values():
            problems.append(f"Service targetPort {p['targetPort']} is no port of the Job's container")
if dep:
    if not matches(dep["spec"]["selector"]["matchLabels"], pod_labels(dep)):
        problems.append("the Deployment's selector does not match its pod template")
    if not isinstance(dep["spec"].get("replicas"), int):
        problems.append("the Deployment has no replica count")

def container_checks(obj, what):
    spec = obj["spec"]["template"]["spec"]
    psc = spec.get("securityContext", {})
    if psc.get("runAsNonRoot") is not True or not psc.get("runAsUser"):
        problems.append(f"{what}: the pod does not run as a non-root user")
    mounts_by_volume = {}
    for c in spec["containers"]:
        sc = c.get("securityContext", {})
        if sc.get("allowPrivilegeEscalation") is not False:
            problems.append(f"{what}: {c['name']} allows privilege escalation")
        if "ALL" not in sc.get("capabilities", {}).get("drop", []):
            problems.append(f"{what}: {c['name']} keeps capabilities")
        for lim in ("cpu", "memory"):
            if lim not in c.get("resources", {}).get("limits", {}):
                problems.append(f"{what}: {c['name']} has no {lim} limit")
        for m in c.get("volumeMounts", []):
            mounts_by_volume[m["name"]] = m["mountPath"]
        args = " ".join(c.get("command", []) + c.get("args", []))
        # Every file the args name under a Secret mount must be a key of that Secret.
        for v in spec.get("volumes", []):
            if "secret" not in v:
                continue
            sname = v["secret"]["secretName"]
            if sname not in secrets:
                problems.append(f"{what}: volume {v['name']} names Secret {sname}, which no template makes")
                continue
            mp = mounts_by_volume.get(v["name"])
            if not mp:
                continue
            for path in re.findall(re.escape(mp) + r"/([\w.-]+)", args):
                if path not in secrets[sname].get("data", {}):
                    problems.append(f"{what}: {mp}/{path} is not a key of Secret {sname}")
    return spec

if dep:
    spec = container_checks(dep, "worker Deployment")
    args = spec["containers"][0].get("args", [])
    ep = args[args.index("--connect") + 1] if "--connect" in args else ""
    m = re.match(r"tcp://([\w.-]+):(\d+)$", ep)
    if not m:
        problems.append(f"the workers' --connect endpoint '{ep}' is not tcp://HOST:PORT")
    elif svc:
        if m.group(1) != svc["metadata"]["name"]:
            problems.append(f"workers connect to {m.group(1)}, the Service is {svc['metadata']['name']}")
        if int(m.group(2)) not in [p["port"] for p in svc["spec"]["ports"]]:
            problems.append(f"workers connect to port {m.group(2)}, which the Service does not offer")
    if "--curve-key" not in args or "--curve-server-key" not in args:
        problems.append("the workers do not use CURVE")
if job:
    spec = container_checks(job, "coordinator Job")
    args = spec["containers"][0].get("args", [])
    for opt in ("--bind", "--curve-secret", "--curve-allow", "--max-wait"):
        if opt not in args:
            problems.append(f"the coordinator Job does not pass {opt}")
    if spec.get("restartPolicy") not in ("Never", "OnFailure"):
        problems.append("the Job's pod restartPolicy must be Never or OnFailure")
ws = secrets.get("photonfarm-worker-curve", {}).get("data", {})
if "coordinator.key" in ws:
    problems.append("the workers' Secret would carry the coordinator's secret key")

for p in problems:
    print(p)
print(f"{len(docs)} objects checked, {len(problems)} problems")
sys.exit(1 if problems else 0)
EOF
        ok "the manifests fit together ($(tail -n 1 "$T/k8s.out"))"
    else
        bad "the manifests fit together"
        show "$T/k8s.out" 20
    fi
else
    skip "python3-yaml not installed (Debian package python3-yaml): the manifests' structure is not checked"
fi

# ---- 4. make-secret.sh ------------------------------------------------------------------

echo "# 4. make-secret.sh"
# secret_file YAML KEY OUT: decodes one data key of the Secrets into OUT.
secret_file() {
    sed -n "s/^  $2: //p" "$1" | head -n 1 | base64 -d >"$3" 2>/dev/null && [ -s "$3" ]
}
if [ "$exes_ok" = 1 ]; then
    if bash "$K8S/make-secret.sh" --photonfarm "$PF" >"$T/secrets.yaml" 2>"$T/secrets.err"; then
        ok "make-secret.sh makes the Secrets"
        mkdir -p "$T/sk"
        all=1
        for k in coordinator.key allowed-workers worker.key coordinator.pub; do
            secret_file "$T/secrets.yaml" "$k" "$T/sk/$k" || all=0
        done
        # Secret key files must not be readable by others (the worker and the
        # coordinator refuse them, like ssh).
        chmod 600 "$T/sk/coordinator.key" "$T/sk/worker.key" 2>/dev/null
        check "the Secrets carry coordinator.key, allowed-workers, worker.key and coordinator.pub" eq "$all" 1
        check "no placeholder is left" hasnt "$T/secrets.yaml" '@[A-Z_]+@'
        csec=$(grep -E '^secret-key' "$T/sk/coordinator.key" | sed 's/.*= *//')
        check "the workers' Secret does not hold the coordinator's secret key" \
            hasnt <(sed -n '/name: photonfarm-worker-curve/,$p' "$T/secrets.yaml" | sed -n 's/^  [a-z.-]*: //p' |
                base64 -d 2>/dev/null) "${csec:-no secret}"
        if [ "$all" = 1 ]; then
            # The keys work: a CURVE render on loopback with exactly these files.
            port=$(free_port)
            timeout 60 "$PF" render "$SPHERES" -o "$T/sk.png" --hdr "$T/sk.pfm" "${TINY[@]}" --threads 1 \
                --bind "tcp://127.0.0.1:$port" --workers 0 --max-wait 30 \
                --curve-secret "$T/sk/coordinator.key" --curve-allow "$T/sk/allowed-workers" \
                >"$T/sk_coord.out" 2>"$T/sk_coord.err" &
            coord=$!
            PIDS+=("$coord")
            timeout 60 "$PFW" --connect "tcp://127.0.0.1:$port" --threads 1 --name k8s-worker --exit-on-bye \
                --curve-key "$T/sk/worker.key" --curve-server-key "$T/sk/coordinator.pub" \
                >"$T/sk_w.out" 2>"$T/sk_w.err" &
            PIDS+=("$!")
            wait "$coord"
            rc=$?
            check "a CURVE render with the Secrets' keys completes (exit $rc)" eq "$rc" 0 || show "$T/sk_coord.err"
            check "... with CURVE on and the one worker key of the Secret allowed" \
                has "$T/sk_coord.err" 'CURVE on: 1 worker key allowed'
            check "... and the worker from the Secret rendered tiles" \
                has "$T/sk_coord.err" 'summary: worker k8s-worker rendered [1-9]'
        fi
    else
        bad "make-secret.sh makes the Secrets"
        show "$T/secrets.err"
    fi
    check "make-secret.sh --keys DIR refuses a directory without keys" \
        eval "! bash $K8S/make-secret.sh --keys $T/nokeys >/dev/null 2>&1"
fi

# ---- 5. the Slurm script -----------------------------------------------------------------

echo "# 5. the Slurm script, with stand-in srun and scontrol"
if [ "$exes_ok" = 1 ]; then
    S=$T/slurm
    mkdir -p "$S/bin" "$S/submit"
    cat >"$S/bin/scontrol" <<'EOF'
#!/usr/bin/env bash
# stand-in: `scontrol show hostnames A,B` prints one name per line.
[ "$1 $2" = "show hostnames" ] || exit 1
tr ',' '\n' <<<"$3"
EOF
    cat >"$S/bin/srun" <<'EOF'
#!/usr/bin/env bash
# stand-in: runs the command once per node of SLURM_JOB_NODELIST, here, with
# SLURMD_NODENAME set as slurmd would; options are logged and dropped.
while [ $# -gt 0 ]; do case $1 in --*) echo "$1" >>"$SRUN_LOG"; shift ;; *) break ;; esac; done
pids=()
for n in $(tr ',' ' ' <<<"$SLURM_JOB_NODELIST"); do
  SLURMD_NODENAME=$n "$@" &
  pids+=($!)
done
trap 'kill -TERM "${pids[@]}" 2>/dev/null' TERM
wait
EOF
    chmod +x "$S/bin/scontrol" "$S/bin/srun"
    cp -r scenes/cornell-spheres "$S/submit/"
    port=$(free_port)
    (cd "$S/submit" && PATH="$S/bin:$PATH" SRUN_LOG="$S/srun.log" SLURM_JOB_ID=4242 SLURM_SUBMIT_DIR="$S/submit" \
        SLURM_JOB_NODELIST=node-a,node-b SLURM_CPUS_ON_NODE=1 PF_BIN="$(dirname "$PF")" PF_PORT="$port" \
        PF_COORD_HOST=127.0.0.1 PF_MAX_WAIT=30 \
        timeout 90 bash "$ROOT/deploy/slurm/photonfarm.sbatch" cornell-spheres/scene.json "${TINY[@]}" \
        --threads 1 >"$S/job.log" 2>&1)
    rc=$?
    # (PF_BIN must hold both executables: the build's bin/ does.)
    check "the Slurm script completes (exit $rc)" eq "$rc" 0 || show "$S/job.log"
    check "it wrote SCENE-JOBID.png and .pfm to the submit directory" \
        test -s "$S/submit/cornell-spheres-4242.png" -a -s "$S/submit/cornell-spheres-4242.pfm"
    check "it removed the job's key directory" test ! -e "$S/submit/.photonfarm-keys-4242"
    check "a worker ran on each of the two nodes, each with its own key (2 worker keys allowed)" \
        has "$S/job.log" 'CURVE on: 2 worker keys allowed'
    check "... both registered (2 workers seen)" has "$S/job.log" 'summary: .*2 workers seen'
    check "the workers' step may share the coordinator's node (srun --overlap)" has "$S/srun.log" '^--overlap$'
    if timeout 60 "$PF" render "$SPHERES" -o "$T/tiny.png" --hdr "$T/tiny.pfm" "${TINY[@]}" --workers 0 \
        >/dev/null 2>"$T/tiny.err"; then
        check "the image is bit-identical to the in-process render" \
            cmp -s "$S/submit/cornell-spheres-4242.pfm" "$T/tiny.pfm"
    else
        bad "in-process reference renders"
        show "$T/tiny.err"
    fi
    (cd "$S/submit" && PATH="$S/bin:$PATH" SLURM_JOB_ID='' bash "$ROOT/deploy/slurm/photonfarm.sbatch" x \
        >"$S/nojob.log" 2>&1)
    rc=$?
    check "outside a Slurm job it refuses to run (exit $rc)" eq "$rc" 2
fi

# ---- 6. the Containerfile ------------------------------------------------------------------

echo "# 6. the Containerfile"
CF=deploy/container/Containerfile
missing=""
for d in $(sed -n 's/^ *add_subdirectory(\([A-Za-z0-9_-]*\).*/\1/p' CMakeLists.txt) deploy scenes; do
    has "$CF" "^COPY $d/ $d/" || missing="$missing $d"
done
if grep -qE 'include\(.*cmake/' CMakeLists.txt && ! has "$CF" '^COPY cmake/ cmake/'; then
    missing="$missing cmake"
fi
check "the build stage copies every folder the build needs${missing:+ (missing:$missing)}" eq "$missing" ""
check "the image runs as a non-root user" has "$CF" '^USER [1-9][0-9]*'
runtime=$(sed -n '/^FROM .*bookworm-slim/,$p' "$CF" | grep -oE '\b(lib[a-z0-9.+-]+[0-9][a-z]?)\b' | sort -u | tr '\n' ' ')
if have apt-cache && apt-cache show libzmq3-dev >/dev/null 2>&1; then
    read -r -a devs < <(sed -n 's/^packages=(\(.*\))/\1/p' deploy/install-deps.sh)
    for dev in "${devs[@]}"; do
        case $dev in lib*-dev) ;; *) continue ;; esac
        deps=$(apt-cache depends "$dev" 2>/dev/null | sed -n 's/^ *Depends: //p' | tr '\n' ' ')
        found=""
        for r in $runtime; do
            case " $deps " in *" $r "*) found=$r ;; esac
        done
        check "the runtime stage installs what $dev depends on (${found:-none of: $deps})" test -n "$found"
    done
else
    skip "apt-cache has no package lists (run apt-get update): the runtime packages are not checked"
fi
if have hadolint; then
    if hadolint "$CF" >"$T/hadolint.out" 2>&1; then ok "hadolint $CF"; else
        bad "hadolint $CF"
        show "$T/hadolint.out"
    fi
else
    skip "hadolint not installed (not packaged in Debian 12): the Containerfile is not linted, and no image is built here"
fi

# ---- 7. install --------------------------------------------------------------------------------

echo "# 7. install.sh and the install rules"
bash deploy/install.sh --help >"$T/inst_help.out" 2>&1
check "install.sh --help describes --prefix, --no-deps and --systemd" \
    has "$T/inst_help.out" '--systemd'
bash deploy/install.sh --no-such-option >/dev/null 2>&1
rc=$?
check "install.sh rejects an unknown option (exit $rc)" eq "$rc" 2
if [ -f "$BUILD/cmake_install.cmake" ] && grep -rqs 'photonfarm-worker' "$BUILD/cmake_install.cmake"; then
    if cmake --install "$BUILD" --prefix "$T/prefix" >"$T/install.out" 2>&1; then
        ok "cmake --install into a temporary prefix"
        for f in bin/photonfarm bin/photonfarm-worker share/doc/photonfarm/cluster.md share/doc/photonfarm/farm.md \
            share/photonfarm/scenes/cornell-spheres/scene.json share/photonfarm/deploy/systemd/photonfarm-worker.service; do
            check "installed $f" test -s "$T/prefix/$f"
        done
        check "the installed photonfarm-worker runs" quiet_ok "$T/prefix/bin/photonfarm-worker" --version
    else
        bad "cmake --install into a temporary prefix"
        show "$T/install.out"
    fi
else
    skip "this build has no install rules yet (add include(cmake/install.cmake) to CMakeLists.txt; deploy/install.sh passes them itself)"
fi

finish
