//! How much memory this process can still use, to refuse a render that
//! would run out of it with a clear message rather than be killed.

/// Bytes the process can still allocate: the smaller of the memory the
/// system has available (`MemAvailable` in `/proc/meminfo`) and what the
/// address-space limit (`ulimit -v`, `/proc/self/limits`) leaves above the
/// process's present size (`VmSize`). `None` where this cannot be read
/// (not Linux); allocations are then only made fallibly.
pub fn available_bytes() -> Option<u64> {
    let meminfo = std::fs::read_to_string("/proc/meminfo").ok()?;
    let mut available = kb_field(&meminfo, "MemAvailable:")?;
    let limits = std::fs::read_to_string("/proc/self/limits").ok();
    let status = std::fs::read_to_string("/proc/self/status").ok();
    if let (Some(limits), Some(status)) = (limits, status)
        && let Some(limit) = address_space_limit(&limits)
        && let Some(size) = kb_field(&status, "VmSize:")
    {
        available = available.min(limit.saturating_sub(size));
    }
    Some(available)
}

/// A `Name:   1234 kB` field, in bytes.
fn kb_field(text: &str, name: &str) -> Option<u64> {
    let line = text.lines().find(|l| l.starts_with(name))?;
    let kb: u64 = line[name.len()..].split_whitespace().next()?.parse().ok()?;
    Some(kb * 1024)
}

/// The soft limit of `Max address space` in `/proc/self/limits`, in bytes;
/// `None` if unlimited.
fn address_space_limit(limits: &str) -> Option<u64> {
    let line = limits
        .lines()
        .find(|l| l.starts_with("Max address space"))?;
    line["Max address space".len()..]
        .split_whitespace()
        .next()?
        .parse()
        .ok()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fields_of_proc_files_are_read() {
        assert_eq!(
            kb_field("MemTotal: 10 kB\nMemAvailable:   2 kB\n", "MemAvailable:"),
            Some(2048)
        );
        let limits = "Limit                     Soft Limit           Hard Limit           Units\n\
                      Max address space         4294967296           unlimited            bytes\n";
        assert_eq!(address_space_limit(limits), Some(4294967296));
        let unlimited =
            "Max address space         unlimited            unlimited            bytes\n";
        assert_eq!(address_space_limit(unlimited), None);
        #[cfg(target_os = "linux")]
        assert!(available_bytes().is_some_and(|b| b > 0));
    }
}
