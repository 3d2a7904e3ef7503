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
        self.camera.as_ref().map(|c| state.orbit.camera(c))
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
struct Pending {
    count: Mutex<usize>,
    idle: Condvar,
}

impl Pending {
    fn add(&self, n: usize) {
        *self.count.lock().expect("pending count") += n;
    }

    fn done(&self, n: usize) {
        let mut c = self.count.lock().expect("pending count");
        *c = c.saturating_sub(n);
        if *c == 0 {
            self.idle.notify_all();
        }
    }
}

/// The window's handle on the worker thread. Dropping it ends the thread after its current job.
pub struct Worker {
    jobs: Sender<Job>,
    replies: Receiver<Reply>,
    pending: Arc<Pending>,
    /// Bytes of the file read so far, and its size.
    progress: Arc<[AtomicU64; 2]>,
}

impl Worker {
    /// Starts a thread that loads `file` with the environment list of `cli_envs`.
    pub fn start(file: &Path, cli_envs: &[String]) -> Worker {
        let (jobs, job_rx) = channel();
        let (reply_tx, replies) = channel();
        let pending = Arc::new(Pending::default());
        pending.add(1);
        let progress = Arc::new([AtomicU64::new(0), AtomicU64::new(0)]);
        let (file, cli_envs) = (file.to_path_buf(), cli_envs.to_vec());
        let (p, prog) = (pending.clone(), progress.clone());
        let spawned = std::thread::Builder::new()
            .name("prt-view worker".into())
            .spawn(move || run(&file, &cli_envs, job_rx, reply_tx, &p, &prog));
        if let Err(e) = spawned {
            // No thread: report it as a load failure through a channel of our own.
            let (tx, rx) = channel();
            let _ = tx.send(Reply::Loaded(Err(PrtError::invalid(
                "viewer",
                format!("starting the worker thread: {e}"),
            ))));
            pending.done(1);
            return Worker {
                jobs,
                replies: rx,
                pending,
                progress,
            };
        }
        Worker {
            jobs,
            replies,
            pending,
            progress,
        }
    }

    pub fn send(&self, job: Job) {
        self.pending.add(1);
        if self.jobs.send(job).is_err() {
            self.pending.done(1);
        }
    }

    /// The next reply, if one is waiting.
    pub fn try_recv(&self) -> Option<Reply> {
        self.replies.try_recv().ok()
    }

    /// Whether jobs are still being worked on.
    pub fn busy(&self) -> bool {
        *self.pending.count.lock().expect("pending count") > 0
    }

    /// (bytes read, file size) of the load.
    pub fn progress(&self) -> (u64, u64) {
        (
            self.progress[0].load(Ordering::Relaxed),
            self.progress[1].load(Ordering::Relaxed),
        )
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

fn run(
    file: &Path,
    cli_envs: &[String],
    jobs: Receiver<Job>,
    replies: Sender<Reply>,
    pending: &Pending,
    progress: &[AtomicU64; 2],
) {
    let (entries, sun, selected) = env_entries(cli_envs);
    let opened = Engine::open_with_progress(file, entries, &|read, total| {
        progress[0].store(read, Ordering::Relaxed);
        progress[1].store(total, Ordering::Relaxed);
    });
    let mut engine = match opened {
        Ok(mut engine) => {
            let mut state = engine.initial_state(selected, sun);
            if let Some(r) = super::cli_sun_radius(cli_envs) {
                state.sun_radius = r;
            }
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
    while let Ok(first) = jobs.recv() {
        // Everything queued behind it; of the render jobs only the newest counts.
        let mut batch = vec![first];
        batch.extend(jobs.try_iter());
        let last_render = batch.iter().rposition(|j| matches!(j, Job::Render(_)));
        for (i, job) in batch.into_iter().enumerate() {
            let reply = match job {
                Job::Render(_) if Some(i) != last_render => None,
                Job::Render(state) => {
                    let cpu = ViewState {
                        gpu: false,
                        ..state
                    };
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
