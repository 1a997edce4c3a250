use super::*;

fn scratch(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "spibench-output-test-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn entries(dir: &Path) -> Vec<String> {
    let mut v: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    v.sort();
    v
}

#[test]
fn files_appear_only_after_commit() {
    let root = scratch("commit");
    let fin = root.join("run");
    let out = OutputDir::create(&fin).unwrap();
    let staging = out.staging_dir().to_path_buf();
    assert!(staging.is_dir());
    let name = staging.file_name().unwrap().to_string_lossy().into_owned();
    assert!(name.starts_with(".run.spibench-partial-"), "{name}");
    std::fs::write(out.path("summary.json"), b"{}").unwrap();
    std::fs::write(out.path("images/a.png"), b"png").unwrap();
    assert!(!fin.exists(), "nothing may appear before commit");
    let done = out.commit().unwrap();
    assert_eq!(done, fin);
    assert_eq!(std::fs::read(fin.join("summary.json")).unwrap(), b"{}");
    assert_eq!(std::fs::read(fin.join("images/a.png")).unwrap(), b"png");
    assert!(!staging.exists());
    // Neither staging nor the lock file remains.
    assert_eq!(entries(&root), vec!["run".to_string()]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn drop_without_commit_leaves_nothing() {
    let root = scratch("drop");
    let fin = root.join("deeper/run");
    {
        let out = OutputDir::create(&fin).unwrap();
        std::fs::write(out.path("images/b.png"), b"half").unwrap();
        assert!(out.staging_dir().exists());
    }
    assert!(!fin.exists());
    // The missing parent made for the staging directory is removed again, too.
    assert!(entries(&root).is_empty(), "{:?}", entries(&root));

    // An existing final directory is left exactly as it was.
    let fin = root.join("existing");
    std::fs::create_dir_all(&fin).unwrap();
    std::fs::write(fin.join("old.txt"), b"old").unwrap();
    let staging;
    {
        let out = OutputDir::create(&fin).unwrap();
        staging = out.staging_dir().to_path_buf();
        std::fs::write(out.path("old.txt"), b"new").unwrap();
    }
    assert!(!staging.exists());
    assert_eq!(entries(&fin), vec!["old.txt".to_string()]);
    assert_eq!(std::fs::read(fin.join("old.txt")).unwrap(), b"old");
    assert_eq!(entries(&root), vec!["existing".to_string()]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn commit_replaces_an_existing_dir() {
    let root = scratch("replace");
    let fin = root.join("run");
    std::fs::create_dir_all(fin.join("images")).unwrap();
    std::fs::write(fin.join("stale.txt"), b"stale").unwrap();
    std::fs::write(fin.join("summary.json"), b"old").unwrap();
    std::fs::write(fin.join("images/old.png"), b"old png").unwrap();
    let out = OutputDir::create(&fin).unwrap();
    std::fs::write(out.path("summary.json"), b"new").unwrap();
    std::fs::write(out.path("images/new.png"), b"new png").unwrap();
    out.commit().unwrap();
    assert_eq!(entries(&fin), vec!["images", "summary.json"]);
    assert_eq!(entries(&fin.join("images")), vec!["new.png"]);
    assert_eq!(std::fs::read(fin.join("summary.json")).unwrap(), b"new");
    assert_eq!(entries(&root), vec!["run".to_string()]);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_failed_rename_falls_back_to_an_in_place_swap() {
    let root = scratch("exdev");
    let fin = root.join("run");
    std::fs::create_dir_all(fin.join("sub")).unwrap();
    std::fs::write(fin.join("stale.txt"), b"stale").unwrap();
    let out = OutputDir::create(&fin).unwrap();
    std::fs::write(out.path("summary.json"), b"new").unwrap();
    std::fs::write(out.path("sub/a.txt"), b"a").unwrap();
    out.finish(true).unwrap();
    assert_eq!(entries(&fin), vec!["sub", "summary.json"]);
    assert_eq!(entries(&fin.join("sub")), vec!["a.txt"]);
    assert_eq!(entries(&root), vec!["run".to_string()]);
    // Copying across devices keeps every byte.
    copy_tree(&fin, &root.join("copy")).unwrap();
    assert_eq!(std::fs::read(root.join("copy/sub/a.txt")).unwrap(), b"a");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_second_run_is_locked_out_and_stale_stagings_are_swept() {
    let root = scratch("lock");
    let fin = root.join("run");
    let out = OutputDir::create(&fin).unwrap();
    let e = OutputDir::create(&fin).unwrap_err();
    assert!(e.is_user_error(), "{e}");
    assert!(e.to_string().contains("another spibench run"), "{e}");
    drop(out);
    // A staging folder and a replaced folder of a process that is gone: with no `run`,
    // the replaced folder is put back; the staging folder is removed.
    if Path::new("/proc/self").exists() {
        let dead = u32::MAX - 7;
        std::fs::create_dir_all(root.join(format!(".run.spibench-partial-{dead}-0"))).unwrap();
        let old = root.join(format!(".run.spibench-old-{dead}-1"));
        std::fs::create_dir_all(&old).unwrap();
        std::fs::write(old.join("kept.txt"), b"kept").unwrap();
        let out = OutputDir::create(&fin).unwrap();
        let staging = out.staging_dir().file_name().unwrap().to_owned();
        let mut want = vec![
            ".run.spibench-lock".to_string(),
            staging.to_string_lossy().into_owned(),
            "run".to_string(),
        ];
        want.sort();
        assert_eq!(entries(&root), want);
        assert_eq!(std::fs::read(fin.join("kept.txt")).unwrap(), b"kept");
        drop(out);
    }
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn names_stay_inside_the_staging_dir() {
    let root = scratch("names");
    let out = OutputDir::create(&root.join("run")).unwrap();
    let p = out.path("../../escape.txt");
    assert!(p.starts_with(out.staging_dir()), "{}", p.display());
    let p = out.path("/abs/x.txt");
    assert!(p.starts_with(out.staging_dir()), "{}", p.display());
    assert!(out.try_path("../x").unwrap_err().is_user_error());
    assert!(out.try_path("/x").is_err());
    assert!(out.try_path("").is_err());
    assert!(out.try_path("a/b.txt").unwrap().parent().unwrap().is_dir());
    drop(out);
    assert!(entries(&root).is_empty(), "{:?}", entries(&root));
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_folder_lock_excludes_staged_runs_and_other_locks() {
    let root = scratch("folder-lock");
    let fin = root.join("deeper/data");
    let lock = FolderLock::acquire(&fin).unwrap();
    assert_eq!(lock.dir(), fin);
    // The parent is made, the folder is not; the lock file sits beside it.
    assert_eq!(entries(&root.join("deeper")), vec![".data.spibench-lock"]);
    let e = FolderLock::acquire(&fin).unwrap_err();
    assert!(
        e.is_user_error() && e.to_string().contains("another spibench run"),
        "{e}"
    );
    let e = OutputDir::create(&fin).unwrap_err();
    assert!(e.to_string().contains("another spibench run"), "{e}");
    // Two shards staged at once, unstaged in either order (the registry alone: nothing is
    // created on disk).
    let (s0, s1) = (
        fin.join(".shard_000000.partial"),
        fin.join(".shard_000001.partial"),
    );
    lock.stage_created(&s0, |_| Ok(())).unwrap();
    lock.stage_created(&s1, |_| Ok(())).unwrap();
    let staged = || {
        live()
            .iter()
            .filter(|e| e.id == lock.id)
            .flat_map(|e| e.staging.clone())
            .collect::<Vec<_>>()
    };
    assert_eq!(staged(), [s0.clone(), s1.clone()]);
    lock.unstage(&s1);
    assert_eq!(staged(), std::slice::from_ref(&s0));
    lock.unstage(&s0);
    assert!(staged().is_empty());
    drop(lock);
    // The parent it made goes again with the lock file.
    assert!(!root.join("deeper").exists());
    let out = OutputDir::create(&fin).unwrap();
    assert!(FolderLock::acquire(&fin).is_err());
    drop(out);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn an_output_that_is_an_input_is_refused() {
    let root = scratch("overlap");
    let a = root.join("a");
    std::fs::create_dir_all(a.join("sub")).unwrap();
    let inputs = vec![a.clone(), root.join("b")];
    for out in [
        a.clone(),
        a.join("."),
        a.join("sub/.."),
        a.join("new"),
        root.clone(),
        root.join("b"),
        root.join("missing/../a"),
    ] {
        let e = refuse_overlap(&out, &inputs, "--out").unwrap_err();
        assert!(e.is_user_error() && e.to_string().contains("--out"), "{e}");
    }
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink(&a, root.join("link")).unwrap();
        assert!(refuse_overlap(&root.join("link"), &inputs, "--out").is_err());
    }
    refuse_overlap(&root.join("c"), &inputs, "--out").unwrap();
    refuse_overlap(&root.join("ab"), &inputs, "--out").unwrap();
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_file_in_the_way_is_an_input_error() {
    let root = scratch("file");
    let fin = root.join("run");
    std::fs::write(&fin, b"i am a file").unwrap();
    let e = OutputDir::create(&fin).unwrap_err();
    assert!(e.is_user_error());
    assert!(e.to_string().contains("run"), "{e}");
    assert!(OutputDir::create(Path::new("/")).is_err());
    // A directory given as `dir/.` stages beside `dir` and replaces it.
    let dotted = root.join("dotted");
    std::fs::create_dir_all(&dotted).unwrap();
    std::fs::write(dotted.join("stale.txt"), b"s").unwrap();
    let out = OutputDir::create(&dotted.join(".")).unwrap();
    assert_eq!(
        out.staging_dir().parent().unwrap(),
        root.canonicalize().unwrap()
    );
    std::fs::write(out.path("x.txt"), b"x").unwrap();
    out.commit().unwrap();
    assert_eq!(entries(&dotted), vec!["x.txt"]);
    let _ = std::fs::remove_dir_all(&root);
}
