//! Build script: with the feature `denoise`, records Open Image Denoise's folder as the
//! binaries' rpath, so that they run without LD_LIBRARY_PATH (the `oidn` crate only links).
//! Without the feature it does nothing.

fn main() {
    println!("cargo:rerun-if-env-changed=OIDN_DIR");
    println!("cargo:rerun-if-env-changed=CARGO_FEATURE_DENOISE");
    if std::env::var_os("CARGO_FEATURE_DENOISE").is_none() {
        return;
    }
    // OIDN_DIR: the setup script's .oidn (see .cargo/config.toml) or the caller's; empty or
    // unset means a system library, which the loader finds by itself.
    let Some(dir) = std::env::var_os("OIDN_DIR").filter(|d| !d.is_empty()) else {
        return;
    };
    let lib = std::path::Path::new(&dir).join("lib");
    let lib = lib.canonicalize().unwrap_or(lib);
    if std::env::consts::OS == "linux" || std::env::consts::OS == "macos" {
        println!("cargo:rustc-link-arg=-Wl,-rpath,{}", lib.display());
    }
}
