# The two commands a user needs (see README.md):
#   make run    set everything up, then run the node on the default scene
#   make test   set everything up, then run the whole test suite
# Set-up is ros_env/bootstrap.py: cached, so a warm run takes seconds.
SHELL := /bin/bash
# DDS discovery stays on this machine unless you say otherwise.
export ROS_AUTOMATIC_DISCOVERY_RANGE ?= LOCALHOST

.PHONY: setup run test test-fast bench bench-gym bench-scale bench-flood bench-cameras bench-latency bench-models bench-urdf bench-bases bench-viewer bench-record bench-vec bench-edits bench-storm bench-pacing bench-soak bench-meshes bench-mesh-corpus bench-spawn-clock bench-respawn bench-sensors bench-controllers bench-laws bench-sdf snapshot clean

setup:
	@python3 ros_env/bootstrap.py

run: setup
	@. .build/env.sh && exec "$$SIM_PREFIX/lib/sim/node" $(ARGS)

test: setup
	@. .build/env.sh && "$$SIM_PYTHON" -m pytest $(PYTEST_ARGS)

# The core, the adapters, the Gym envs and the linters: under a minute (no node, browser or window)
test-fast: setup
	@. .build/env.sh && "$$SIM_PYTHON" -m pytest -m "not slow" $(PYTEST_ARGS)

bench: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/run_all.py

bench-gym: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/gym_step.py

bench-scale: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/scale.py

bench-flood: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/command_flood.py

# Service latency with the world stepping at 1 kHz, against the same world paused (40 s)
bench-latency: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/latency.py

# N worlds at once: our vector env, Gymnasium's, EnvPool's (installed once into .build), ~4 min
bench-vec: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/vector.py

# How long each kind of edit holds the world lock (100 boxes stepping), ~1 min
bench-edits: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/edits.py

# The longest /clock gap while 8 clients spawn and delete 50 boxes each, ~1 min
bench-storm: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/storm.py

# Pacing and stopping in wall time: the factor kept, no burst after a stall, exit times, ~40 s
bench-pacing: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/pacing.py

# The node's resident memory over storms, spawns, deletes and world loads, against where it
# began (issue 45: within 50 MiB), with resets and a mixed storm (issue 52), ~2.5 min
bench-soak: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/soak.py

bench-cameras: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/cameras.py

# Robot files from robosuite, gymnasium-robotics and dm_control (fetched once into .build/corpus)
bench-models: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/models.py

# ROS robots (URDF, xacro, Collada) from description packages: read, convert, compile, spawn,
# second spawn and /clock stalls, ~3 min (BENCH_URDF=all: every file of the ROS corpus)
bench-urdf: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/urdf.py

# SDF worlds: a 3,000-shape world's load over MuJoCo's of the same MJCF, its steps/s over bare
# mj_step, a world of 20 model:// folders with meshes loaded again (cached), ~2 min
bench-sdf: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/sdf.py

# Mobile bases: steps/s with the rover driven over idle (real_time_factor 0), odometry rate, ~40 s
bench-bases: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/bases.py

# Large and malformed meshes over the wire: decided/refused in bounds, memory back, ~1 min
bench-meshes: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/mesh_limits.py

# Meshes of the robot corpus and made from it (unwelded, welded, scanned, degenerate, random,
# malformed): decided/refused in bounds, a few minutes
bench-mesh-corpus: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/mesh_corpus.py

# Robots of the corpus spawned and deleted at real-time factor 1: does /clock stand still?
bench-spawn-clock: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/spawn_clock.py

# A robot spawned again after its delete: first and second spawn against MuJoCo's compile
bench-respawn: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/respawn.py

# Declared sensors of a mobile manipulator: their rates kept, their cost in steps/s, ~1 min
bench-sensors: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/sensors.py

# A robot's controllers at 1 kHz: steps/s over the same robot held without them, ~1 min
bench-controllers: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/controllers.py

bench-laws: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/laws.py

bench-viewer: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/viewer.py

bench-record: setup
	@. .build/env.sh && "$$SIM_PYTHON" benchmarks/recording.py

# A PNG of a scene: make snapshot [SCENE=default] [OUT=snapshot.png] [ARGS='--camera overview']
SCENE ?= default
OUT ?= snapshot.png
snapshot: setup
	@. .build/env.sh && "$$SIM_PYTHON" -m sim_node.snapshot $(SCENE) -o $(OUT) $(ARGS)

clean:
	rm -rf .venv .build .pytest_cache
