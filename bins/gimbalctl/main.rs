fn main() {
    eprintln!("gimbalctl: not built yet");
    std::process::exit(1);
}
