function [answer, status] = spm_request(method, base_url, resource, body)
%SPM_REQUEST  Send a struct as a JSON body ('PUT' or 'POST'); the decoded answer
%   and the HTTP status.
%
%   MATLAB: webwrite with weboptions('MediaType', 'application/json',
%   'RequestMethod', method). webwrite raises on an error status and does not give
%   the body then: answer holds the error message in 'detail' and an empty
%   'failed'; the reasons of a refusal are those of POST /check.
%
%   GNU Octave: its webwrite cannot send a JSON body (a struct is refused,
%   MediaType is ignored), so the request goes through curl (system), which gives
%   the status and the body of every answer, a refusal's reasons included.
%
%   With a token, set the environment variable SPM_TOKEN (as for the server).
  url = [base_url resource];
  token = getenv('SPM_TOKEN');
  if exist('OCTAVE_VERSION', 'builtin')
    [answer, status] = curl_request(method, url, body, token);
    return
  end
  options = weboptions('MediaType', 'application/json', ...
                       'RequestMethod', lower(method), 'Timeout', 30);
  if ~isempty(token)
    options.HeaderFields = {'Authorization', ['Bearer ' token]};
  end
  try
    answer = webwrite(url, body, options);
    status = 200;
  catch err
    found = regexp(err.identifier, 'HTTP(\d+)', 'tokens', 'once');
    if isempty(found)
      rethrow(err);
    end
    status = str2double(found{1});
    answer = struct('detail', err.message, 'failed', struct('check', {}, 'reason', {}));
  end
end

function [answer, status] = curl_request(method, url, body, token)
  body_file = [tempname() '.json'];
  answer_file = [tempname() '.json'];
  cleanup = onCleanup(@() delete_files({body_file, answer_file}));
  fid = fopen(body_file, 'w');
  fwrite(fid, jsonencode(body));
  fclose(fid);
  auth = '';
  if ~isempty(token)
    auth = sprintf(' -H "Authorization: Bearer %s"', token);
  end
  command = sprintf(['curl -s -S --max-time 30 -X %s -H "Content-Type: application/json"' ...
                     '%s --data-binary "@%s" -o "%s" -w "%%{http_code}" "%s"'], ...
                    method, auth, body_file, answer_file, url);
  [failed, output] = system(command);
  if failed
    error('spm:request', '%s %s: curl failed (exit status %d): %s', ...
          method, url, failed, strtrim(output));
  end
  status = str2double(strtrim(output));
  text = fileread(answer_file);
  if isempty(strtrim(text))
    answer = struct();
  else
    answer = jsondecode(text);
  end
end

function delete_files(names)
  for k = 1:numel(names)
    if exist(names{k}, 'file')
      delete(names{k});
    end
  end
end
