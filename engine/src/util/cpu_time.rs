//! CPU time, for measurements that should not depend on other load on the machine: the calling
//! thread's (`CLOCK_THREAD_CPUTIME_ID`: single-thread ray rates, `bench-scene`) and the whole
//! process's (`getrusage`: the pilot of `simulate plan`, on all threads). Both in seconds; other
//! processes on the same cores slow them less than wall time (shared caches still do).

/// CPU time of the calling thread, s; `None` where the clock cannot be read.
pub fn thread_seconds() -> Option<f64> {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid timespec to write into; the clock id is a constant.
    if unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) } != 0 {
        return None;
    }
    Some(ts.tv_sec as f64 + 1e-9 * ts.tv_nsec as f64)
}

/// CPU time (user + system) this process has used so far, s; `None` where it cannot be read.
pub fn process_seconds() -> Option<f64> {
    // SAFETY: getrusage writes into the zeroed struct it is given and reads nothing else.
    let mut u: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut u) } != 0 {
        return None;
    }
    let t = |v: libc::timeval| v.tv_sec as f64 + v.tv_usec as f64 * 1e-6;
    Some(t(u.ru_utime) + t(u.ru_stime))
}

#[cfg(test)]
mod tests {
    /// Both clocks read, and advance with work done on this thread.
    #[test]
    fn clocks_advance_with_work() {
        let (t0, p0) = (
            super::thread_seconds().unwrap(),
            super::process_seconds().unwrap(),
        );
        let mut x = 0u64;
        let start = std::time::Instant::now();
        while start.elapsed().as_secs_f64() < 0.05 {
            x = x.wrapping_mul(6364136223846793005).wrapping_add(1);
        }
        std::hint::black_box(x);
        assert!(super::thread_seconds().unwrap() > t0);
        assert!(super::process_seconds().unwrap() > p0);
    }
}
