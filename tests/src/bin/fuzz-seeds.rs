//! `fuzz-seeds OUT [--record FILE] [--store DIR]`: writes the fuzz targets' starting corpora
//! (see `mission_tests::fuzz::seed`) from the conformance corpora, the deployment and,
//! when given, a real run's record and store.

fn main() -> std::io::Result<()> {
    let mut args = std::env::args().skip(1);
    let out = std::path::PathBuf::from(args.next().unwrap_or_else(|| "fuzz/corpus".into()));
    let (mut record, mut store) = (None, None);
    while let Some(a) = args.next() {
        match a.as_str() {
            "--record" => record = args.next().map(std::path::PathBuf::from),
            "--store" => store = args.next().map(std::path::PathBuf::from),
            other => return Err(std::io::Error::other(format!("unknown argument `{other}`"))),
        }
    }
    let corpora = [mission_tests::shared().join("conformance")];
    let counts = mission_tests::fuzz::seed(&out, &corpora, record.as_deref(), store.as_deref())?;
    for (target, n) in counts {
        println!("{target}: {n} seeds");
    }
    Ok(())
}
