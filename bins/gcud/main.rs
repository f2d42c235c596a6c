fn main() {
    eprintln!("gcud: not built yet");
    std::process::exit(1);
}
