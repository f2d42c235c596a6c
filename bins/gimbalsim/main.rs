fn main() {
    eprintln!("gimbalsim: not built yet");
    std::process::exit(1);
}
