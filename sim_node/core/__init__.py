"""
The ROS-free MuJoCo world: no rclpy or message imports here.

Modules, one job each: :mod:`.world` (the lock, the generation, the recompile, and the public
methods that lock, validate and delegate), :mod:`.index` (names and addresses of one model),
:mod:`.control` (joint commands), :mod:`.guard` (divergence), :mod:`.editor` (MjSpec edits),
:mod:`.state` (reading and writing state), :mod:`.sources` (what can be spawned),
:mod:`.loop` (the stepping thread), :mod:`.checks` and :mod:`.quat` (shared helpers).

Threading contract
------------------
* **One lock.** A :class:`~.world.World` owns one lock. Every public method of ``World``
  takes it (properties too) and releases it before returning; helpers that assume it is held
  end in ``_locked``. It is reentrant, so code inside ``World.locked()`` may call any public
  method. Only ``Control.stage`` (joint commands) runs
  outside it, under the control's own staging lock, which is never held while waiting for the
  world lock. No other lock is taken while holding the world lock, so there is no order to get
  wrong.
* **Who may take it.** Any thread. MuJoCo releases the GIL while stepping and compiling, so the
  lock is what keeps readers from seeing torn state. A plain lock is not fair: the loop calls
  ``World.wait_for_callers`` before each batch, and callers waiting for the lock go first.
* **Who steps.** Only the stepping loop (:class:`~.loop.SimLoop`, its own thread) calls
  ``World.step`` in the node; a script or the Gym environment that owns its world steps it
  from its own thread instead. Nobody calls ``mj_step`` outside ``World``.
* **Changes.** Spawn, delete, reset, set-state and physics parameters are validated, then
  applied between steps under the lock, all or nothing: spec edits go to a copy of the spec
  that becomes the world's only if it recompiles (``World._edit_locked``). Every recompile
  raises the generation and swaps model, data, index, control binding and guard together.
* **Snapshots.** ``World.snapshot`` is the one producer: it copies what publishers need under
  the lock and numbers it (``seq``). The loop makes one per batch at ``snapshot_rate_hz``, and
  services make one after a change; :class:`~.loop.SimLoop` keeps only the newest by ``seq``,
  so a consumer never sees time go backwards because two threads raced to publish.
* **ROS.** The loop thread never calls rclpy; the node reads snapshots, never MjData.
"""
