"""
The ROS-free MuJoCo world: no rclpy or message imports here.

Folders that are layers, each importing only those below it (a test runs Tarjan over folders):
:mod:`.base` at the bottom (configuration, typed errors, immutable records, input checks,
quaternions, memory given back), then :mod:`.models` (what users bring: model files, meshes,
assets, URDF and xacro) and :mod:`.devices` (what a model carries that looks at the world:
sensor groups, contacts, the renderer), :mod:`.compiled` (one compiled model: its index of
names and addresses, its state read and written), :mod:`.control` (joint commands, torques,
trajectories, mobile bases, controllers' rules), :mod:`.stepping` (the world lock, the live
state and its design, the steps, divergence) and :mod:`.editing` (structural edits and state
writes through one commit path). On top, in this folder, what uses the whole world: the facade
:mod:`.world` (what every user of the core talks to: the lock, reads, stepping, reset, edits;
its public methods lock, validate and delegate), :mod:`.loop` (the stepping thread),
:mod:`.cameras` and :mod:`.lidar` (camera rigs and laser scanners, which read the world through
it) and :mod:`.query` (which entities match a query). The paths scripts import by, kept:
:mod:`.config`, :mod:`.errors` and :mod:`.records` (each re-exports its module of
:mod:`.base`), :mod:`.bases` and :mod:`.sources`.

Threading contract
------------------
* **One world lock, one order.** A :class:`~.world.World` owns one lock. Every public method
  of ``World`` takes it (properties too) and releases it before returning; helpers that assume
  it is held end in ``_locked``. It is reentrant, so code inside ``World.locked()`` may call any
  public method. The order (``docs/threading.md``, with every thread of the node):
  ``Transaction.edit_lock`` (:mod:`.editing.transaction`), then the world lock, then leaves
  that are never held while taking another lock: the loop's condition and its snapshots'
  (:class:`~.stepping.snapshots.Snapshots`), the control's staging lock (commands are staged
  outside the world lock and applied under it), the world lock's own waiter count, the queue
  of edits waiting for their turn. The loop reads what a batch needs
  (``world.stepping.clock_since_batch()``, or ``World.clock``) before taking its condition,
  and takes the world lock once per batch (``world.stepping.batch``: the steps, the clock and
  the snapshot, with no MuJoCo call but the steps while the state is clean); a step request's
  feedback runs with no lock of the loop held; ``SimLoop.step`` inside ``World.locked()`` is
  refused (the loop could never take its steps).
* **Who may take it.** Any thread. MuJoCo releases the GIL while stepping and compiling, so the
  lock is what keeps readers from seeing torn state. A plain lock is not fair: the loop calls
  ``world.stepping.wait_for_callers`` before each batch, and callers waiting for the lock go first.
* **Who steps.** Only the stepping loop (:class:`~.loop.SimLoop`, its own thread) calls
  ``World.step`` in the node; a script or the Gym environment that owns its world steps it
  from its own thread instead. Nobody calls ``mj_step`` outside ``World``.
* **Changes.** Spawn, delete, reset, set-state and physics parameters are validated, then
  applied between steps, all or nothing, through one commit path (``Transaction.change``,
  :mod:`.editing.transaction`, over the edit phase's state :class:`~.stepping.design.Design`):
  under
  the lock the edit is planned and the current spec taken; with the lock released a copy of the
  spec is edited and compiled and everything that does not need the live state is prepared
  (index, name matching, new data); under the lock again the state is carried over by names and
  model, data, index, control binding and guard are swapped together (a few milliseconds,
  whatever the model's size), raising the generation. Structural edits take turns on
  ``Transaction.edit_lock``, which is taken before the world lock, never while holding it (an edit
  called inside ``World.locked()`` is done wholly under the world lock instead). Spawns and
  deletes that queued meanwhile are made together, one compile and one commit for the group,
  or one by one if the group fails anywhere. If the world changed while an edit compiled, it
  is planned again. The world keeps its spec uncompiled (a
  compiled spec holds every processed mesh: copying it took 190 ms with three arms), and MuJoCo
  reads only checked copies of files (:mod:`.models.assets`).
* **Snapshots.** ``World.snapshot`` (and ``world.stepping.batch``, for the loop) is the one
  producer: it copies what publishers need under the lock and numbers it (``seq``). The loop
  makes one per batch at ``snapshot_rate_hz``, and services make one after a change;
  :class:`~.stepping.snapshots.Snapshots` keeps only the newest by ``seq``, so a consumer never
  sees time go backwards because two threads raced to publish.
* **ROS.** The loop thread never calls rclpy; the node reads snapshots, never MjData.
"""
