"""Where the batches of clips run: this process, a local process pool, or Ray tasks (local or on a cluster).

Each engine is a generator of ``(batch, contacts, clips)`` in the order the batches finish, so the caller writes
each batch's part as soon as it is done; no engine schedules anything itself.  Leaving the generator early (an
error, Ctrl-C) cancels the batches not yet started.
"""
import multiprocessing

from mjccd.collection.checks import check_clips
from mjccd.errors import InputError

ENGINES = ("pool", "ray")


def in_process(batches, options):
    """The batches one after another in this process (one worker: no process to start)."""
    for batch in batches:
        yield (batch, *check_clips(batch, options))


def _check_batch(work):
    """One batch in a pool worker: ``(batch, contacts, clips)``."""
    batch, options = work
    return (batch, *check_clips(batch, options))


def process_pool(batches, options, workers):
    """The batches on ``workers`` local processes (started fresh: ``spawn``, safe with numba's threads); the
    workers are stopped at once when the caller stops early (Ctrl-C, an error)."""
    pool = multiprocessing.get_context("spawn").Pool(workers)
    try:
        yield from pool.imap_unordered(_check_batch, [(batch, options) for batch in batches])
        pool.close()
    except BaseException:
        pool.terminate()
        raise
    finally:
        pool.join()


def ray_tasks(batches, options, workers, address=None):
    """The batches as Ray tasks: on a local Ray of ``workers`` CPUs (started and stopped here), or on the
    cluster at ``address`` (every worker needs mjccd installed and the clips at the same paths)."""
    ray = _ray()
    started = not ray.is_initialized()
    if started:
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, log_to_driver=False, logging_level="ERROR")
        else:
            ray.init(address=address, log_to_driver=False, logging_level="ERROR")
    remote = ray.remote(num_cpus=1)(check_clips)
    pending = {remote.remote(batch, options): batch for batch in batches}
    try:
        while pending:
            finished, _ = ray.wait(list(pending), num_returns=1)
            for ref in finished:
                batch = pending.pop(ref)
                yield (batch, *ray.get(ref))
    finally:
        for ref in pending:
            ray.cancel(ref, force=True)
        if started:
            ray.shutdown()


def _ray():
    try:
        import ray
    except ImportError:
        raise InputError("engine 'ray' needs Ray: pip install 'mjccd[ray]'") from None
    return ray


def check_engine(engine, address=None):
    """Refuse an unknown engine, an address without Ray, or Ray where it does not import, before any work."""
    if engine not in ENGINES:
        raise InputError(f"engine: expected one of {', '.join(ENGINES)}, got {engine!r}")
    if engine == "ray":
        _ray()
    elif address is not None:
        raise InputError("address: only the 'ray' engine runs on a cluster")


def run_batches(batches, options, *, engine="pool", workers=1, address=None):
    """The engine's generator for ``batches`` (lists of :class:`~mjccd.collection.clips.ClipTask`); ``engine`` and
    ``address`` as :func:`check_engine` passed them."""
    if engine == "ray":
        return ray_tasks(batches, options, workers, address)
    return in_process(batches, options) if workers == 1 else process_pool(batches, options, workers)
