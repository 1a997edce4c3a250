//! Making a dataset's shards: each shard's samples in a parallel loop, its files written while
//! the next shards' samples are computed, its commit (rename, manifest) in index order.
//!
//! A shard's writing cannot keep pace with many threads alone. Its largest file (the objects,
//! 18.4 of a shard's 30.2 MB in the scaling spec) is encoded, hashed and written as one stream:
//! some 19 ms of the shard's 31 ms of writing on one thread of the 2-core machine, while 16
//! threads compute the 250 samples of the next shard in about as long (1.13 ms each on one
//! thread). Writing one shard beside the next one's samples, as before,
//! made that file the pace of the job. Here up to [`WRITES_IN_FLIGHT`] shards are written at
//! once, each as soon as its samples exist, on the same thread pool; the next sample loop waits
//! only when that many are still writing.

use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::{Mutex, MutexGuard, mpsc};
use std::time::{Duration, Instant};

use rayon::prelude::*;

use super::{
    CommitSeconds, FileHash, Manifest, Prepared, Sample, ShardEntry, manifest_text, shard_dir_name,
    write_locked,
};
use crate::error::{Error, Result};
use crate::report::output::FolderLock;

/// Shards whose files may be in writing at once: while a shard is sampled, up to two earlier
/// ones are written beside it, twice the writing one shard's sample loop could hide before.
/// It is also the most shards held in memory at once (about 30 MB each in the scaling spec;
/// two before).
pub(super) const WRITES_IN_FLIGHT: usize = 3;

/// The shards in writing at once on `threads` threads: [`WRITES_IN_FLIGHT`], but one on a
/// single thread, where no write overlaps a sample loop (the thread runs the write only when it
/// waits): each shard is then written and committed before the next one's samples, so that an
/// interrupted run keeps every shard but the one in progress.
fn writes_in_flight(threads: usize) -> usize {
    if threads <= 1 { 1 } else { WRITES_IN_FLIGHT }
}

/// A shard's files, written in its staging folder and not yet renamed into place.
struct Written {
    staging: PathBuf,
    files: Vec<FileHash>,
    samples: u64,
    seconds: f64,
}

/// Makes the shards `todo`, in order, into the folder `lock` holds, and commits each (its
/// entry added to `manifest`, `committed(b)` called). Shards are committed one at a time, in
/// index order, each by a rename followed by the manifest's rewrite, so the folder and a resume
/// are the same as with no overlap; the write that completes a shard's turn commits it (and any
/// ready after it), so commits too run beside the sample loops. The first error by shard order
/// is returned; the shards before it stay committed (a resume continues from them), and those
/// after it are removed. Returns the shards written, the seconds spent in the sample loops and
/// where the commits' time went.
pub(super) fn make_shards(
    prep: &Prepared,
    lock: &FolderLock,
    manifest: &mut Manifest,
    todo: &[u64],
    committed: &(dyn Fn(u64) + Sync),
) -> Result<(u64, f64, CommitSeconds)> {
    let (mut sample_seconds, mut waited, mut held) = (0.0, 0.0, 0.0);
    // A write's end, as a wake-up call for a loop waiting for room.
    let (tx, rx) = mpsc::channel::<()>();
    let state = Mutex::new(State {
        order: Order {
            todo,
            next: 0,
            arrived: BTreeMap::new(),
            in_flight: 0,
            error: None,
        },
        manifest,
        times: CommitSeconds::default(),
    });
    let shared = &state;
    let most = writes_in_flight(rayon::current_num_threads());
    // FIFO: a thread that runs pending writes while it waits (`wait`) takes the oldest first,
    // the next to commit; newest first (rayon's `spawn`) left every older shard unwritten, and
    // so nothing committed, until the last sample loop had ended.
    let last_writes = rayon::scope_fifo(|s| {
        // Moved in: a receiver is not shared between threads.
        let rx = rx;
        for &b in todo {
            // The memory bound: wait for a write to end when as many are in flight.
            let t = Instant::now();
            while locked(shared).order.in_flight >= most {
                wait(&rx);
            }
            waited += t.elapsed().as_secs_f64();
            if locked(shared).order.error.is_some() {
                break;
            }
            let t = Instant::now();
            let samples = prep.shard_samples_timed(b);
            sample_seconds += t.elapsed().as_secs_f64();
            let samples = match samples {
                Ok((v, tail)) => {
                    held += tail;
                    v
                }
                Err(e) => {
                    locked(shared).order.fail(b, e);
                    break;
                }
            };
            locked(shared).order.in_flight += 1;
            let tx = tx.clone();
            s.spawn_fifo(move |_| {
                let w = write_shard(prep, lock, b, &samples);
                drop(samples);
                locked(shared).finish(prep, lock, committed, b, w);
                // The receiver outlives the scope: the send cannot fail.
                let _ = tx.send(());
            });
        }
        // The last writes, which nothing overlaps: the scope's end waits for them.
        Instant::now()
    });
    waited += last_writes.elapsed().as_secs_f64();
    let State {
        mut order, times, ..
    } = state.into_inner().unwrap_or_else(|e| e.into_inner());
    // Written after the first error (or after a shard whose error came first): removed.
    for (_, w) in std::mem::take(&mut order.arrived) {
        if let Ok(w) = w {
            discard(lock, &w.staging);
        }
    }
    match order.error {
        Some((_, e)) => Err(e),
        None => Ok((
            todo.len() as u64,
            sample_seconds,
            CommitSeconds {
                waited,
                held,
                ..times
            },
        )),
    }
}

/// What the writes share: the commit order, the manifest and the commits' seconds.
struct State<'a> {
    order: Order<'a>,
    manifest: &'a mut Manifest,
    times: CommitSeconds,
}

impl State<'_> {
    /// Takes shard b's ended write and commits every shard whose turn has come.
    fn finish(
        &mut self,
        prep: &Prepared,
        lock: &FolderLock,
        committed: &(dyn Fn(u64) + Sync),
        b: u64,
        w: Result<Written>,
    ) {
        let State {
            order,
            manifest,
            times,
        } = self;
        order.receive(b, w);
        order.commit_ready(&mut |b, w| {
            times.arrays += w.seconds;
            times.manifest += commit_written(prep, lock, manifest, b, w)?;
            committed(b);
            Ok(())
        });
    }
}

fn locked<'m, 'a>(m: &'m Mutex<State<'a>>) -> MutexGuard<'m, State<'a>> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

/// The shards' writes as they end, in any order, and their commits in `todo`'s order.
struct Order<'a> {
    todo: &'a [u64],
    /// The position in `todo` of the next shard to commit.
    next: usize,
    arrived: BTreeMap<u64, Result<Written>>,
    in_flight: usize,
    /// The first error by shard order, with its shard.
    error: Option<(u64, Error)>,
}

impl Order<'_> {
    fn receive(&mut self, b: u64, w: Result<Written>) {
        self.in_flight -= 1;
        self.arrived.insert(b, w);
    }

    fn fail(&mut self, b: u64, e: Error) {
        if self.error.as_ref().is_none_or(|(f, _)| b < *f) {
            self.error = Some((b, e));
        }
    }

    /// Commits every shard whose turn has come and whose files are written; stops at an
    /// error (a failed write, or a commit's own), which ends the job after the writes in
    /// flight.
    fn commit_ready(&mut self, commit: &mut impl FnMut(u64, Written) -> Result<()>) {
        while let Some(&b) = self.todo.get(self.next) {
            if self.error.as_ref().is_some_and(|(f, _)| *f <= b) {
                return;
            }
            let Some(w) = self.arrived.remove(&b) else {
                return;
            };
            self.next += 1;
            if let Err(e) = w.and_then(|w| commit(b, w)) {
                self.fail(b, e);
                return;
            }
        }
    }
}

/// Waits for a write to end. The waiting thread runs the pool's pending work meanwhile (it is
/// one of the pool's threads: the sample loops run in it), and otherwise sleeps until a write
/// ends or briefly, so that it neither holds a core nor misses work that appears. A wake-up
/// may be stale (a write that ended before the wait): the caller checks again.
fn wait(rx: &mpsc::Receiver<()>) {
    loop {
        if rx.try_recv().is_ok() {
            return;
        }
        if rayon::yield_now() != Some(rayon::Yield::Executed) {
            match rx.recv_timeout(Duration::from_micros(200)) {
                Ok(()) => return,
                Err(mpsc::RecvTimeoutError::Timeout) => {}
                // `make_shards` holds a sender until its scope has ended.
                Err(mpsc::RecvTimeoutError::Disconnected) => unreachable!("a sender is alive"),
            }
        }
    }
}

/// Writes shard b of `samples` in its staging folder (the arrays side by side, each encoded,
/// hashed and written as it goes). A signal removes the folder until it is committed or
/// discarded; on an error it is removed here.
fn write_shard(prep: &Prepared, lock: &FolderLock, b: u64, samples: &[Sample]) -> Result<Written> {
    let t0 = Instant::now();
    let staging = lock.dir().join(format!(".{}.partial", shard_dir_name(b)));
    crate::report::output::refuse_link(&staging, "shard staging folder")?;
    let _ = std::fs::remove_dir_all(&staging);
    let files = lock
        .stage_created(&staging, |p| std::fs::create_dir_all(p))
        .map_err(|e| Error::write(&staging, e))
        .and_then(|()| {
            let files: Vec<Result<FileHash>> = prep
                .schema()
                .into_par_iter()
                .map(|a| {
                    let file = format!("{}.npy", a.name);
                    let sha256 = prep.write_array(&staging.join(&file), &a, b, samples)?;
                    Ok(FileHash {
                        name: a.name,
                        file,
                        sha256,
                    })
                })
                .collect();
            // The first failing array's error in schema order, on any thread count.
            crate::error::in_order(files)
        });
    match files {
        Ok(files) => Ok(Written {
            staging,
            files,
            samples: samples.len() as u64,
            seconds: t0.elapsed().as_secs_f64(),
        }),
        Err(e) => {
            discard(lock, &staging);
            Err(e)
        }
    }
}

/// Commits shard b's written files: the staging folder renamed into place, then the manifest
/// rewritten with its entry. Returns the seconds of the manifest's rewrite.
fn commit_written(
    prep: &Prepared,
    lock: &FolderLock,
    manifest: &mut Manifest,
    b: u64,
    w: Written,
) -> Result<f64> {
    let dir = lock.dir();
    let name = shard_dir_name(b);
    let final_dir = dir.join(&name);
    if let Err(e) = std::fs::rename(&w.staging, &final_dir) {
        discard(lock, &w.staging);
        return Err(Error::write(&final_dir, e));
    }
    lock.unstage(&w.staging);
    let t = Instant::now();
    manifest.shards.push(ShardEntry {
        index: b,
        first_sample: b * prep.spec.file.shard_samples,
        samples: w.samples,
        dir: name,
        files: w.files,
    });
    write_locked(lock, "manifest.json", manifest_text(manifest)?.as_bytes())?;
    Ok(t.elapsed().as_secs_f64())
}

/// Removes a staging folder that will not be committed.
fn discard(lock: &FolderLock, staging: &std::path::Path) {
    let _ = std::fs::remove_dir_all(staging);
    lock.unstage(staging);
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(b: u64) -> Result<Written> {
        Ok(Written {
            staging: PathBuf::from(format!("s{b}")),
            files: Vec::new(),
            samples: b,
            seconds: 0.0,
        })
    }

    /// Feeds the writes' ends in `arrivals` (shard, failed) and returns the shards committed,
    /// in commit order, and the shard of the error kept.
    fn run(
        todo: &[u64],
        arrivals: &[(u64, bool)],
        sample_error: Option<u64>,
    ) -> (Vec<u64>, Option<u64>) {
        let mut order = Order {
            todo,
            next: 0,
            arrived: BTreeMap::new(),
            in_flight: arrivals.len(),
            error: None,
        };
        if let Some(b) = sample_error {
            order.fail(b, Error::input("sampling failed"));
        }
        let mut done = Vec::new();
        let mut commit = |b: u64, w: Written| -> Result<()> {
            assert_eq!(w.samples, b, "shard {b} got another shard's files");
            done.push(b);
            Ok(())
        };
        for &(b, failed) in arrivals {
            let w = if failed {
                Err(Error::input(format!("shard {b}")))
            } else {
                written(b)
            };
            order.receive(b, w);
            order.commit_ready(&mut commit);
        }
        assert_eq!(order.in_flight, 0);
        (done, order.error.map(|(b, _)| b))
    }

    #[test]
    fn writes_ending_out_of_order_commit_in_shard_order() {
        let todo = [3, 4, 5, 6];
        let (done, error) = run(
            &todo,
            &[(5, false), (4, false), (3, false), (6, false)],
            None,
        );
        assert_eq!(done, [3, 4, 5, 6]);
        assert_eq!(error, None);
    }

    #[test]
    fn the_first_error_by_shard_stops_the_commits_after_it() {
        // Shard 5's write fails after shard 6's ended: 3 and 4 commit, 6 does not.
        let todo = [3, 4, 5, 6];
        let (done, error) = run(
            &todo,
            &[(6, false), (3, false), (5, true), (4, false)],
            None,
        );
        assert_eq!(done, [3, 4]);
        assert_eq!(error, Some(5));
        // A later shard's failure does not replace an earlier one's.
        let (done, error) = run(&todo, &[(4, true), (6, true), (3, false)], None);
        assert_eq!(done, [3]);
        assert_eq!(error, Some(4));
        // Shard 6's samples failed (so it was never written): the shards before it commit.
        let (done, error) = run(&todo, &[(5, false), (3, false), (4, false)], Some(6));
        assert_eq!(done, [3, 4, 5]);
        assert_eq!(error, Some(6));
        // A failed write of an earlier shard than the failed samples is the error returned.
        let (done, error) = run(&todo, &[(4, true), (3, false)], Some(5));
        assert_eq!(done, [3]);
        assert_eq!(error, Some(4));
    }
}
