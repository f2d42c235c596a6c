//! gimbal-web's sign-in cannot be turned against its users (issue 49),
//! end to end over plain HTTP (no browser): the real gimbal-web in front of gcud and its simulated buses, behind a "proxy"
//! that is the test itself on 127.0.0.1 (`[http] trusted_proxy`), naming
//! its clients in `X-Forwarded-For`.

use super::access::raw;
use super::*;

/// The stack with `http` as its `[http]` section.
fn stack_with(http: &str) -> Stack {
    let gimbals = "[[gimbal]]\nname = \"mast-1\"\naddress = \"5.1.1\"\n\
                   [[gimbal]]\nname = \"mast-2\"\naddress = \"5.2.1\"\n\
                   [[gimbal]]\nname = \"absent\"\naddress = \"5.2.9\"\n";
    Stack::with(start_gcud(), |clients, state| {
        format!(
            "gcud = \"{clients}\"\nlisten = \"127.0.0.1:0\"\nsource_group = {DOOR_GROUP}\nstate_file = \"{}\"\n[http]\n{http}{USERS}{gimbals}",
            state.display()
        )
    })
}

/// A sign-in's status and answer, from `client` through the proxy (`None`:
/// from the proxy's own address).
fn sign_in(stack: &Stack, user: &str, password: &str, client: Option<&str>) -> (u16, String) {
    let body = json!({ "user": user, "password": password }).to_string();
    let mut headers = vec![("Content-Type", "application/json")];
    if let Some(c) = client {
        headers.push(("X-Forwarded-For", c));
    }
    raw(&stack.url, "POST", "/api/sign-in", &headers, &body)
}

const PROXY: &str = "trusted_proxy = \"127.0.0.1\"\n";

/// Issue 49: behind one proxy address, a guesser's wrong passwords for
/// admin kept the administrator's right password at 429. Now failures
/// count per account and client address: the guesser is refused, the
/// administrator elsewhere signs in.
#[test]
fn wrong_guesses_for_admin_never_refuse_its_right_password_from_another_address() {
    let stack = stack_with(PROXY);
    let statuses: Vec<u16> = (0..30)
        .map(|_| sign_in(&stack, "admin", "guess", Some("203.0.113.66")).0)
        .collect();
    assert_eq!(statuses[0], 401, "{statuses:?}");
    assert!(statuses.contains(&429), "the guesser is held back: {statuses:?}");
    for client in [Some("198.51.100.7"), Some("6.6.6.6, 198.51.100.8"), None] {
        let (status, answer) = sign_in(&stack, "admin", "admin-secret", client);
        assert_eq!(
            status,
            200,
            "admin from {client:?} while guessed at:\n{answer}\n{}",
            stack.log()
        );
    }
    let (status, _) = sign_in(&stack, "admin", "admin-secret", Some("203.0.113.66"));
    assert_eq!(status, 429, "the guesser's own address waits, right password or not");
}

/// Issue 49: 1,024 addresses trying 600 times a second filled the table
/// of addresses, and every address not seen before was refused. A flood
/// from 2,048 addresses refuses no fresh address's sign-in.
#[test]
fn a_flood_from_many_addresses_never_refuses_a_fresh_address() {
    let stack = stack_with(PROXY);
    let started = Instant::now();
    let sent: usize = std::thread::scope(|s| {
        let threads: Vec<_> = (0..4u32)
            .map(|t| {
                let stack = &stack;
                s.spawn(move || {
                    let mut n = 0;
                    while started.elapsed() < Duration::from_secs(3) || n < 512 {
                        let i = t * 512 + (n as u32 % 512);
                        let client = format!("10.{t}.{}.{}", i / 256 % 256, i % 256);
                        let (status, answer) = sign_in(stack, "admin", "guess", Some(&client));
                        assert!(status == 401 || status == 429, "{answer}");
                        n += 1;
                    }
                    n
                })
            })
            .collect();
        threads.into_iter().map(|t| t.join().expect("flood thread")).sum()
    });
    let rate = sent as f64 / started.elapsed().as_secs_f64();
    eprintln!("flood: {sent} wrong sign-ins from 2048 addresses, {rate:.0} a second");
    let (status, answer) = sign_in(&stack, "admin", "admin-secret", Some("192.0.2.200"));
    assert_eq!(
        status, 200,
        "a fresh address's right password after the flood:\n{answer}"
    );
    let (status, answer) = sign_in(&stack, "viewer", "wrong", Some("192.0.2.201"));
    assert_eq!(
        status, 401,
        "a fresh address's wrong password is checked, not refused:\n{answer}"
    );
}
