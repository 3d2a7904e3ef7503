//! The window's worker thread: it owns an [`Engine`] and does everything that may take longer
//! than a frame (loading the file, preparing a light, the CPU relights and their errors, saving,
//! uploading the transport to the GPU). The window sends it jobs and polls its replies; of a run
//! of queued render jobs only the newest is done.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{Receiver, Sender, channel};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use super::{Engine, EnvEntry, LightShown, Limits, Rendered, ViewState, env_entries, save_view};
use crate::error::{PrtError, Result};
use crate::relight::LightContext;
use crate::relight::gpu::{Gpu, GpuTransport};
use crate::scene::Camera;
use crate::store::transport::Transport;

/// What the window asks for.
pub enum Job {
    Render(ViewState),
    AutoExposure(ViewState),
    Save(ViewState, PathBuf),
    Upload(Gpu),
}

/// A loaded file: what the window needs to draw on the GPU by itself.
pub struct Loaded {
    pub transport: Arc<Transport>,
    pub ctx: Arc<LightContext>,
    pub envs: Vec<EnvEntry>,
    pub limits: Limits,
    /// A state that suits the file (see [`Engine::initial_state`]).
    pub state: ViewState,
    /// The camera a per-vertex bake was made with; `None` for a per-pixel bake.
    pub camera: Option<Camera>,
    /// The size of the images shown.
    pub size: (usize, usize),
}

impl Loaded {
    /// The camera `state` looks through, as [`Engine::camera`] gives it.
    pub fn camera(&self, state: &ViewState) -> Option<Camera> {
        self.camera.as_ref().map(|c| state.camera_of(c))
    }
}

/// What the worker answers.
pub enum Reply {
    Loaded(Result<Loaded>),
    Light(LightShown),
    Rendered(Result<Rendered>),
    Exposure(Result<f32>),
    Saved(Result<PathBuf>),
    Uploaded(Result<Arc<GpuTransport>>),
}

/// Jobs sent and not yet answered, with a condition to wait on.
#[derive(Default)]
pub struct Pending {
    count: Mutex<usize>,
    idle: Condvar,
}

impl Pending {
    /// `n` more jobs to answer.
    pub fn add(&self, n: usize) {
        *self.count.lock().expect("pending count") += n;
    }

    /// `n` jobs answered.
    pub fn done(&self, n: usize) {
        let mut c = self.count.lock().expect("pending count");
        *c = c.saturating_sub(n);
        if *c == 0 {
            self.idle.notify_all();
        }
    }
}

/// A window's handle on its worker thread: jobs `J` go in, replies `R` come out, and it counts
/// the jobs not yet answered. Dropping it ends the thread after its current job. Both windows
/// use it: the transport's ([`Job`], [`Reply`]) and the volume's.
pub struct Worker<J, R> {
    jobs: Sender<J>,
    replies: Receiver<R>,
    pending: Arc<Pending>,
}

impl<J: Send + 'static, R: Send + 'static> Worker<J, R> {
    /// Starts a thread named `name` running `body` on the jobs, a sender of replies and the
    /// pending count, which `body` marks done as it answers. `initial` jobs are pending from the
    /// start (a load the thread begins with); `failed` makes the one reply that says the thread
    /// could not start.
    pub fn start(
        name: &str,
        initial: usize,
        body: impl FnOnce(Receiver<J>, Sender<R>, Arc<Pending>) + Send + 'static,
        failed: impl FnOnce(String) -> R,
    ) -> Worker<J, R> {
        let (jobs, job_rx) = channel();
        let (reply_tx, replies) = channel();
        let pending = Arc::new(Pending::default());
        pending.add(initial);
        let p = pending.clone();
        let spawned = std::thread::Builder::new()
            .name(name.into())
            .spawn(move || body(job_rx, reply_tx, p));
        match spawned {
            Ok(_) => Worker {
                jobs,
                replies,
                pending,
            },
            Err(e) => {
                // No thread: the failure is the one reply, through a channel of our own.
                let (tx, rx) = channel();
                let _ = tx.send(failed(format!("starting the worker thread: {e}")));
                pending.done(initial);
                Worker {
                    jobs,
                    replies: rx,
                    pending,
                }
            }
        }
    }

    /// Sends a job (counted as pending until the thread answers it).
    pub fn send(&self, job: J) {
        self.pending.add(1);
        if self.jobs.send(job).is_err() {
            self.pending.done(1);
        }
    }

    /// The next reply, if one is waiting.
    pub fn try_recv(&self) -> Option<R> {
        self.replies.try_recv().ok()
    }

    /// Whether jobs are still being worked on.
    pub fn busy(&self) -> bool {
        *self.pending.count.lock().expect("pending count") > 0
    }

    /// Blocks until every job sent has been answered, or `timeout` passed; returns whether idle.
    pub fn wait_idle(&self, timeout: Duration) -> bool {
        let c = self.pending.count.lock().expect("pending count");
        let (c, _) = self
            .pending
            .idle
            .wait_timeout_while(c, timeout, |c| *c > 0)
            .expect("pending count");
        *c == 0
    }
}

/// The next job and everything queued behind it, waiting for one when none is queued: what a
/// worker does in one go (of a run of renders only the newest counts). `None` once the window
/// has gone.
pub fn next_batch<J>(jobs: &Receiver<J>) -> Option<Vec<J>> {
    let first = jobs.recv().ok()?;
    let mut batch = vec![first];
    batch.extend(jobs.try_iter());
    Some(batch)
}

/// The transport window's worker, and the bytes of the file it has read so far and the file's
/// size.
pub struct TransportWorker {
    /// The worker.
    pub worker: Worker<Job, Reply>,
    progress: Arc<[AtomicU64; 2]>,
}

impl TransportWorker {
    /// Starts a thread that loads `file` with the environment list of `cli_envs`.
    pub fn start(file: &Path, cli_envs: &[String]) -> TransportWorker {
        let progress = Arc::new([AtomicU64::new(0), AtomicU64::new(0)]);
        let (file, cli_envs, prog) = (file.to_path_buf(), cli_envs.to_vec(), progress.clone());
        let worker = Worker::start(
            "prt-view worker",
            1,
            move |jobs, replies, pending| run(&file, &cli_envs, jobs, replies, &pending, &prog),
            |e| Reply::Loaded(Err(PrtError::invalid("viewer", e))),
        );
        TransportWorker { worker, progress }
    }

    /// (bytes read, file size) of the load.
    pub fn progress(&self) -> (u64, u64) {
        (
            self.progress[0].load(Ordering::Relaxed),
            self.progress[1].load(Ordering::Relaxed),
        )
    }
}

fn run(
    file: &Path,
    cli_envs: &[String],
    jobs: Receiver<Job>,
    replies: Sender<Reply>,
    pending: &Pending,
    progress: &[AtomicU64; 2],
) {
    let (entries, light) = env_entries(cli_envs);
    let opened = Engine::open_with_progress(file, entries, &|read, total| {
        progress[0].store(read, Ordering::Relaxed);
        progress[1].store(total, Ordering::Relaxed);
    });
    let mut engine = match opened {
        Ok(mut engine) => {
            let state = engine.initial_state(light);
            let loaded = Loaded {
                transport: engine.transport.clone(),
                ctx: engine.ctx.clone(),
                envs: engine.envs.clone(),
                limits: engine.limits(),
                camera: engine.camera(&ViewState::default()),
                size: engine.view_size(),
                state,
            };
            let _ = replies.send(Reply::Loaded(Ok(loaded)));
            // The initial state's light, prepared for its exposure: later lights come with the
            // renders that prepare them.
            if let Some(light) = engine.current_light() {
                let _ = replies.send(Reply::Light(light));
            }
            pending.done(1);
            engine
        }
        Err(e) => {
            let _ = replies.send(Reply::Loaded(Err(e)));
            pending.done(1);
            return;
        }
    };
    while let Some(batch) = next_batch(&jobs) {
        // Of the render jobs only the newest counts.
        let last_render = batch.iter().rposition(|j| matches!(j, Job::Render(_)));
        for (i, job) in batch.into_iter().enumerate() {
            let reply = match job {
                Job::Render(_) if Some(i) != last_render => None,
                Job::Render(state) => {
                    let mut cpu = state;
                    cpu.display.gpu = false;
                    let r = engine.render_with(&cpu, &mut |light| {
                        let _ = replies.send(Reply::Light(light.clone()));
                    });
                    Some(Reply::Rendered(r))
                }
                Job::AutoExposure(state) => Some(Reply::Exposure(engine.auto_exposure(&state))),
                Job::Save(state, stem) => Some(Reply::Saved(
                    save_view(&mut engine, &state, &stem).map(|()| stem),
                )),
                Job::Upload(gpu) => Some(Reply::Uploaded(
                    GpuTransport::upload(&gpu, &engine.transport, None).map(Arc::new),
                )),
            };
            if let Some(r) = reply
                && replies.send(r).is_err()
            {
                return;
            }
            pending.done(1);
        }
    }
}
