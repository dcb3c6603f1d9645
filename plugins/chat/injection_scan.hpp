// The prompt-injection scan (RCAN AI safety gates: auth -> scope -> rate limit -> injection scan -> ...). One scanner
// for every brain, run by chat before any brain sees the text, so no provider can forget it. It looks for attempts
// to rewrite a brain's instructions ("ignore all previous instructions", "you are now", chat-template tokens) and to
// talk a brain out of the robot's safety ("disable the e-stop"), on a normalized copy of the text (case, zero-width
// characters, punctuation and digit-for-letter spellings folded away). A block is final: the brain is never asked.
//
// This is a tripwire, not the defence: whatever a brain answers is still validated against the declared
// capabilities and their bounds and dispatched through the e-stop and scope checks, so a missed injection can at most
// propose a command the caller could have sent anyway.
#pragma once

#include <string>
#include <string_view>

namespace rcand::plugins::chat {

struct InjectionVerdict {
  bool blocked = false;
  std::string rule;  // which rule matched: "override_instructions", "role_change", ...
};

InjectionVerdict scan_for_injection(std::string_view text);

}  // namespace rcand::plugins::chat
