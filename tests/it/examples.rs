//! The commands the guides show, run as shown: every `console` block of `README.md` and
//! `docs/**/*.md` is a trycmd case (`$ command`, `? status`, then the output, with trycmd's
//! `[..]` and `...` where output varies), each run in the `.in` folder beside its page, so a
//! changed output fails here. `TRYCMD=overwrite` writes the new output into the page.

use mission_tests::{bin, repo};

#[test]
fn the_guides_examples_print_what_they_show() {
    let cases = trycmd::TestCases::new();
    cases
        .register_bin("trace", bin("trace"))
        .case(repo().join("README.md"))
        .case(repo().join("docs/*.md"))
        .case(repo().join("docs/guide/*.md"));
}
