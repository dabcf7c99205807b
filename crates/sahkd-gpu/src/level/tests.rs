//! Checks of the level builder's plumbing that need no GPU: every kernel's bindings are read
//! from its WGSL, and the phases keep the names the CLI prints.

use super::kernels::level_sources;
use super::{Phase, PHASES};
use crate::kernel::{declared_bindings, Arg};

#[test]
fn every_level_kernel_declares_readable_bindings() {
    let sources = level_sources();
    assert_eq!(sources.len(), 14, "kernels in level.wgsl");
    for (name, source) in sources {
        let bindings = declared_bindings(&source).unwrap_or_else(|e| panic!("{name}: {e}"));
        assert_eq!(bindings[0], ("params".to_string(), Arg::Uniform), "{name}");
        assert!(
            source.contains(&format!("fn {name}(")),
            "{name}: entry point in its section"
        );
        // A binding declared read-only is never assigned in the kernel (naga rejects that too,
        // but only when the module is compiled on a device).
        for (binding, arg) in &bindings[1..] {
            assert_ne!(*arg, Arg::Uniform, "{name}: {binding}");
        }
    }
}

#[test]
fn phases_keep_their_names_and_order() {
    let names: Vec<&str> = Phase::ALL.iter().map(|p| p.name()).collect();
    assert_eq!(names, PHASES);
    for (i, p) in Phase::ALL.iter().enumerate() {
        assert_eq!(*p as usize, i);
    }
}
